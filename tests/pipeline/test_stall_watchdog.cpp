// The stall watchdog: a source that stops delivering frames is reported once, at once after
// the timeout, and cleared when frames come back; its timeout follows the slowest full-field
// scan. And the heartbeat carries the fault bits with state LOST while stalled.
#include <gtest/gtest.h>

#include "sempose/can_output/can_pose_sink.hpp"
#include "sempose/hal/can_memory_channel.hpp"
#include "sempose/ipc/protocol.hpp"
#include "sempose/pipeline/stall_watchdog.hpp"

namespace sempose::pipeline {
namespace {

constexpr std::int64_t kS = 1'000'000'000;

TEST(StallWatchdog, ReportsOnceAndClearsWhenFramesReturn) {
  StallWatchdog w(2 * kS, 0);
  EXPECT_EQ(w.update(1, kS / 2), StallWatchdog::Change::kNone);
  EXPECT_EQ(w.update(2, kS), StallWatchdog::Change::kNone);
  EXPECT_EQ(w.update(2, 2 * kS), StallWatchdog::Change::kNone) << "silent 1 s: within the timeout";
  EXPECT_EQ(w.update(2, 3 * kS + 1), StallWatchdog::Change::kStalled);
  EXPECT_TRUE(w.stalled());
  EXPECT_EQ(w.update(2, 10 * kS), StallWatchdog::Change::kNone) << "reported once, not every call";
  EXPECT_EQ(w.update(3, 11 * kS), StallWatchdog::Change::kRecovered);
  EXPECT_FALSE(w.stalled());
  EXPECT_EQ(w.update(3, 14 * kS), StallWatchdog::Change::kStalled);
  EXPECT_EQ(w.stalls(), 2u);
}

TEST(StallWatchdog, TimeoutFollowsTheSlowestFullFieldScan) {
  hal::ScanLimits l;
  l.field_w = 1024;
  l.field_h = 768;
  l.max_dwell_ns = 100;
  l.line_flyback_ns = 0;
  EXPECT_EQ(StallWatchdog::timeout_for(l), 2 * kS) << "fast scans: the 2 s floor";
  l.max_dwell_ns = 10'000;  // 7.9 s per full field
  EXPECT_NEAR(static_cast<double>(StallWatchdog::timeout_for(l)), 3.0 * 1024 * 768 * 10'000, 1e6);
}

TEST(StallWatchdog, HeartbeatCarriesTheFaultBits) {
  hal::MemoryCanChannel ch;
  can_output::CanPoseSink sink(ch, {});
  PipelineStatus s;
  s.state = pose::TrackState::kLost;  // what the output stage reports while stalled
  s.fault_bits = kFaultSourceStalled | kFaultOutputWrite;
  sink.service(s, 0);
  ASSERT_GE(ch.sent_count(), 1u);
  ipc::Heartbeat h;
  ASSERT_TRUE(ipc::decode_heartbeat(ch.sent(0).data, 8, h));
  EXPECT_TRUE(h.stalled);
  EXPECT_TRUE(h.output_fault);
  EXPECT_EQ(h.state, ipc::WireState::kLost);
}

}  // namespace
}  // namespace sempose::pipeline
