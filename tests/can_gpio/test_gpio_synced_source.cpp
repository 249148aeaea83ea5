// GpioSyncedSource against a scripted scan source and a pipe-backed edge source: done only
// with both the inner scan and an edge; timeouts complete the frame flagged; missed, late and
// spurious edges are counted; no allocation on the RT path.
#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "sempose/hal/gpio_synced_source.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "scripted_source.hpp"

namespace hal = sempose::hal;

namespace {

// Edges through a non-blocking pipe, one int64 timestamp each (a GPIO line's fd in production).
class PipeEdges final : public hal::EdgeSource {
 public:
  PipeEdges() {
    if (::pipe2(fds_, O_NONBLOCK | O_CLOEXEC) != 0) fds_[0] = fds_[1] = -1;
  }
  ~PipeEdges() override {
    ::close(fds_[0]);
    ::close(fds_[1]);
  }
  int fd() const noexcept override { return fds_[0]; }
  int read_edges(std::int64_t* ts, int max) noexcept override {
    int n = 0;
    while (n < max && ::read(fds_[0], &ts[n], sizeof ts[n]) == static_cast<ssize_t>(sizeof ts[n])) ++n;
    return n;
  }
  void edge(std::int64_t t) { ASSERT_EQ(::write(fds_[1], &t, sizeof t), static_cast<ssize_t>(sizeof t)); }

 private:
  int fds_[2]{-1, -1};
};

struct Fixture : ::testing::Test {
  sempose::test::ScriptedSource inner;
  PipeEdges edges;
  hal::FramePool pool{1, 16};
  hal::GpioSyncedSource src{inner, edges, 500'000};  // 0.5 ms timeout
  hal::FrameSlot& slot = pool[0];
  hal::ScanRequest req{};
};

}  // namespace

TEST_F(Fixture, DoneNeedsBothTheInnerScanAndAnEdge) {
  EXPECT_EQ(src.wait_fd(), edges.fd());
  ASSERT_EQ(src.start(req, slot), hal::StartResult::kStarted);
  EXPECT_EQ(src.poll(), hal::PollResult::kBusy);
  inner.finish();
  inner.set_now(1'000'000);
  EXPECT_EQ(src.poll(), hal::PollResult::kBusy) << "scan done but no frame-sync edge yet";
  edges.edge(1'200'000);
  EXPECT_EQ(src.poll(), hal::PollResult::kDone);
  EXPECT_EQ(slot.meta.t_scan_end_ns, 1'200'000) << "the edge is the interrupt";
  EXPECT_EQ(slot.meta.status, hal::FrameStatus::kOk);
  EXPECT_EQ(src.counters().edges.load(), 1u);
  EXPECT_EQ(src.counters().missed.load(), 0u);
}

TEST_F(Fixture, EdgeBeforeTheInnerScanFinishesStillCounts) {
  ASSERT_EQ(src.start(req, slot), hal::StartResult::kStarted);
  edges.edge(900'000);
  EXPECT_EQ(src.poll(), hal::PollResult::kBusy);
  inner.finish();
  EXPECT_EQ(src.poll(), hal::PollResult::kDone);
  EXPECT_EQ(slot.meta.t_scan_end_ns, 1'000'000) << "the later of the two times";
}

TEST_F(Fixture, MissingEdgeTimesOutFlaggedAndTheLateEdgeIsCounted) {
  ASSERT_EQ(src.start(req, slot), hal::StartResult::kStarted);
  inner.finish();
  inner.set_now(1'400'000);
  EXPECT_EQ(src.poll(), hal::PollResult::kBusy);
  inner.set_now(1'500'000);  // expected end 1 ms + 0.5 ms timeout
  EXPECT_EQ(src.poll(), hal::PollResult::kDone);
  EXPECT_EQ(slot.meta.status, hal::FrameStatus::kBad);
  EXPECT_EQ(src.counters().missed.load(), 1u);
  edges.edge(1'600'000);  // the edge of the frame already completed
  ASSERT_EQ(src.start(req, slot), hal::StartResult::kStarted);
  EXPECT_EQ(src.counters().late.load(), 1u);
  inner.finish();
  EXPECT_EQ(src.poll(), hal::PollResult::kBusy) << "the late edge must not complete the next frame";
  edges.edge(2'700'000);
  EXPECT_EQ(src.poll(), hal::PollResult::kDone);
  EXPECT_EQ(slot.meta.status, hal::FrameStatus::kOk);
}

TEST_F(Fixture, EdgesWithoutAScanAreSpurious) {
  edges.edge(1);
  edges.edge(2);
  EXPECT_EQ(src.poll(), hal::PollResult::kIdle);
  EXPECT_EQ(src.counters().spurious.load(), 2u);
  ASSERT_EQ(src.start(req, slot), hal::StartResult::kStarted);
  edges.edge(10);
  edges.edge(11);  // a second edge in one scan
  inner.finish();
  EXPECT_EQ(src.poll(), hal::PollResult::kDone);
  EXPECT_EQ(src.counters().spurious.load(), 3u);
  EXPECT_EQ(src.counters().edges.load(), 4u);
}

TEST_F(Fixture, PollingDoesNotAllocate) {
  sempose::rt::alloc::ScopedArm arm;
  for (int i = 0; i < 200; ++i) {
    ASSERT_EQ(src.start(req, slot), hal::StartResult::kStarted);
    src.poll();
    inner.finish();
    edges.edge(i);
    ASSERT_EQ(src.poll(), hal::PollResult::kDone);
  }
  EXPECT_EQ(sempose::rt::alloc::this_thread_allocations(), 0u);
}
