// rt/ primitives against the peers a developer would reach for: a mutex-guarded std::deque
// for the ring, a mutex-guarded struct for the mailbox. Cross-thread figures (two threads
// handing items over) matter most: that is how the pipeline uses them.
#include <benchmark/benchmark.h>

#include <atomic>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>

#include "sempose/rt/latency_histogram.hpp"
#include "sempose/rt/mailbox.hpp"
#include "sempose/rt/spsc_ring.hpp"

namespace {

struct Plan {
  std::int32_t x, y, w, h;
  std::uint32_t dwell_ns, flags;
};

class MutexQueue {
 public:
  bool try_push(std::uint64_t v) {
    std::lock_guard<std::mutex> g(m_);
    if (q_.size() >= 1024) return false;
    q_.push_back(v);
    return true;
  }
  bool try_pop(std::uint64_t& v) {
    std::lock_guard<std::mutex> g(m_);
    if (q_.empty()) return false;
    v = q_.front();
    q_.pop_front();
    return true;
  }

 private:
  std::mutex m_;
  std::deque<std::uint64_t> q_;
};

// Items per second handed from a producer thread to the benchmark thread.
template <typename Queue>
void handover(benchmark::State& state) {
  static Queue q;
  std::atomic<bool> stop{false};
  std::thread producer([&] {
    std::uint64_t i = 0;
    while (!stop.load(std::memory_order_relaxed)) {
      if (q.try_push(i)) ++i;
    }
  });
  std::uint64_t v = 0, got = 0;
  for (auto _ : state) {
    while (!q.try_pop(v)) {
    }
    benchmark::DoNotOptimize(v);
    ++got;
  }
  stop = true;
  producer.join();
  while (q.try_pop(v)) {
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(got));
}
void BM_HandoverSpscRing(benchmark::State& s) { handover<sempose::rt::SpscRing<std::uint64_t, 1024>>(s); }
void BM_HandoverMutexDeque(benchmark::State& s) { handover<MutexQueue>(s); }
BENCHMARK(BM_HandoverSpscRing)->UseRealTime();
BENCHMARK(BM_HandoverMutexDeque)->UseRealTime();

// Reads of the latest plan while another thread keeps publishing.
void BM_ReadUnderWritesMailbox(benchmark::State& state) {
  static sempose::rt::Mailbox<Plan> box;
  std::atomic<bool> stop{false};
  std::thread writer([&] {
    std::int32_t i = 0;
    while (!stop.load(std::memory_order_relaxed)) box.publish({i, i, 192, 192, 250, 0}), ++i;
  });
  for (auto _ : state) benchmark::DoNotOptimize(box.read());
  stop = true;
  writer.join();
}
void BM_ReadUnderWritesMutex(benchmark::State& state) {
  static std::mutex m;
  static Plan plan{};
  std::atomic<bool> stop{false};
  std::thread writer([&] {
    std::int32_t i = 0;
    while (!stop.load(std::memory_order_relaxed)) {
      std::lock_guard<std::mutex> g(m);
      plan = {i, i, 192, 192, 250, 0};
      ++i;
    }
  });
  for (auto _ : state) {
    std::lock_guard<std::mutex> g(m);
    benchmark::DoNotOptimize(plan);
  }
  stop = true;
  writer.join();
}
BENCHMARK(BM_ReadUnderWritesMailbox)->UseRealTime();
BENCHMARK(BM_ReadUnderWritesMutex)->UseRealTime();

void BM_HistogramRecord(benchmark::State& state) {
  static sempose::rt::LatencyHistogram h("bench");
  std::int64_t v = 0;
  for (auto _ : state) {
    h.record_ns(v);
    v = (v + 7919) % 5'000'000;
  }
}
BENCHMARK(BM_HistogramRecord);

}  // namespace

BENCHMARK_MAIN();
