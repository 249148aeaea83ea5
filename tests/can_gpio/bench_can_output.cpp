// What one pose costs on the output stage: encoding alone, CanPoseSink over the in-memory
// channel (encode + two sends), and over the candump-log channel (encode + format + ring copy).
// The peer is snprintf formatting the same log line (what a naive log sink would do).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <string>
#include <unistd.h>

#include "sempose/can_output/can_pose_sink.hpp"
#include "sempose/hal/can_candump_log.hpp"
#include "sempose/hal/can_memory_channel.hpp"

namespace co = sempose::can_output;
namespace hal = sempose::hal;
namespace ipc = sempose::ipc;
namespace pl = sempose::pipeline;

namespace {

pl::PoseRecord pose(std::uint32_t i) {
  pl::PoseRecord p;
  p.pose_seq = i;
  p.x_px = 100.0 + (i % 100) * 0.37;
  p.y_px = 50.0 - (i % 50) * 0.11;
  p.phi_deg = (i % 360) - 179.5;
  p.score = 0.9f;
  p.nm_per_px = 40;
  return p;
}

void BM_EncodeClassicPose(benchmark::State& state) {
  std::uint8_t xy[8], at[8];
  std::uint32_t i = 0;
  for (auto _ : state) {
    const auto v = co::CanPoseSink::to_values(pose(i++), 1'000'000);
    ipc::encode_pose_xy(v, xy);
    ipc::encode_pose_attr(v, at);
    benchmark::DoNotOptimize(xy);
    benchmark::DoNotOptimize(at);
  }
}
BENCHMARK(BM_EncodeClassicPose);

void BM_PublishMemoryChannel(benchmark::State& state) {
  hal::MemoryCanChannel ch(1 << 16);
  co::CanPoseSink sink(ch, {});
  std::uint32_t i = 0;
  for (auto _ : state) {
    if (ch.sent_count() > (1 << 16) - 4) ch.clear_sent();
    benchmark::DoNotOptimize(sink.publish(pose(i++), 1'000'000));
  }
}
BENCHMARK(BM_PublishMemoryChannel);

void BM_PublishCandumpLog(benchmark::State& state) {
  const std::string path = "/tmp/sempose_bench_" + std::to_string(::getpid()) + ".log";
  sempose::rt::Status st;
  auto ch = hal::CandumpLogChannel::open({path, "can0", 1 << 20, false, false}, st);
  co::CanPoseSink sink(*ch, {});
  std::uint32_t i = 0;
  for (auto _ : state) {
    if ((i & 4095) == 0) {
      state.PauseTiming();
      ch->flush();  // the non-RT flusher's job, kept out of the measurement
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(sink.publish(pose(i++), 1'000'000));
  }
  ch.reset();
  std::remove(path.c_str());
}
BENCHMARK(BM_PublishCandumpLog);

void BM_FormatLineOwn(benchmark::State& state) {
  hal::CanFrame f;
  f.id = 0x101;
  f.len = 8;
  char buf[hal::CandumpLogChannel::kMaxLine];
  std::int64_t t = 1'600'000'000'123'456'000;
  for (auto _ : state) {
    benchmark::DoNotOptimize(hal::CandumpLogChannel::format_line(f, t++, "can0", buf));
  }
}
BENCHMARK(BM_FormatLineOwn);

void BM_FormatLineSnprintfPeer(benchmark::State& state) {
  hal::CanFrame f;
  f.id = 0x101;
  f.len = 8;
  char buf[hal::CandumpLogChannel::kMaxLine];
  std::int64_t t = 1'600'000'000'123'456'000;
  for (auto _ : state) {
    int n = std::snprintf(buf, sizeof buf, "(%010lld.%06lld) %s %03X#", static_cast<long long>(t / 1'000'000'000),
                          static_cast<long long>(t % 1'000'000'000 / 1000), "can0", f.id);
    for (int k = 0; k < f.len; ++k) n += std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "%02X", f.data[k]);
    buf[n++] = '\n';
    ++t;
    benchmark::DoNotOptimize(n);
  }
}
BENCHMARK(BM_FormatLineSnprintfPeer);

}  // namespace

BENCHMARK_MAIN();
