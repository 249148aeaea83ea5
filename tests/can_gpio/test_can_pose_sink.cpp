// CanPoseSink over the in-memory channel: pose frames (classic and FD), heartbeat rate and
// contents, command validation, counters, and no allocation on the RT path.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "sempose/can_output/can_pose_sink.hpp"
#include "sempose/hal/can_memory_channel.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace co = sempose::can_output;
namespace hal = sempose::hal;
namespace ipc = sempose::ipc;
namespace pl = sempose::pipeline;

namespace {

pl::PoseRecord pose(std::uint8_t target, std::uint32_t seq) {
  pl::PoseRecord p;
  p.target = target;
  p.pose_seq = seq;
  p.state = sempose::pose::TrackState::kTracking;
  p.x_px = 100.25 + seq;
  p.y_px = -3.5;
  p.phi_deg = 12.5;
  p.score = 0.9f;
  p.nm_per_px = 40.0;
  p.t_scan_end_ns = 1'000'000;
  p.dwell_ns = 250;
  p.target_scale = 1.0625;
  p.sigma_x_px = 0.125;
  p.sigma_y_px = 0.25;
  p.sigma_phi_deg = 0.2;
  p.sigma_scale = 0.004;
  return p;
}

hal::CanFrame command(std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
  hal::CanFrame f;
  f.id = id;
  for (auto b : bytes) f.data[f.len++] = b;
  return f;
}

}  // namespace

TEST(CanPoseSink, ClassicPoseIsThreeFramesWithTheSameSequence) {
  hal::MemoryCanChannel ch;
  co::CanPoseSink sink(ch, {});
  ASSERT_EQ(sink.publish(pose(1, 300), 3'500'000), pl::PublishResult::kSent);
  ASSERT_EQ(ch.sent_count(), 3u);
  // The uncertainty frame: σ in 0.1 nm at the set's nm/px, σφ in mdeg, the target's scale.
  const auto& un = ch.sent(2);
  EXPECT_EQ(un.id, 0x113u);
  ipc::PoseUnc du;
  ASSERT_TRUE(ipc::decode_pose_unc(un.data, un.len, du));
  EXPECT_EQ(du.sigma_x_dnm, 50);   // 0.125 px * 40 nm/px = 5.0 nm
  EXPECT_EQ(du.sigma_y_dnm, 100);
  EXPECT_EQ(du.sigma_phi_mdeg, 200);
  EXPECT_EQ(du.target_scale_e4, 5625);  // (1.0625 - 0.5) * 10 000
  EXPECT_EQ(du.sigma_scale, 8);         // 0.004 / 0.0005
  EXPECT_EQ(du.seq, 300 % 256);
  const auto& xy = ch.sent(0);
  const auto& at = ch.sent(1);
  EXPECT_EQ(xy.id, 0x110u);
  EXPECT_EQ(at.id, 0x111u);
  ipc::PoseXy dxy;
  ipc::PoseAttr da;
  ASSERT_TRUE(ipc::decode_pose_xy(xy.data, xy.len, dxy));
  ASSERT_TRUE(ipc::decode_pose_attr(at.data, at.len, da));
  EXPECT_EQ(dxy.x_nm, 16010);   // (100.25 + 300) px * 40 nm/px
  EXPECT_EQ(dxy.y_nm, -140);
  EXPECT_EQ(dxy.seq, 300 % 256);
  EXPECT_EQ(da.seq, dxy.seq);
  EXPECT_EQ(da.phi_mdeg, 12500);
  EXPECT_EQ(da.score_milli, 900);
  EXPECT_EQ(da.age_us, 2504);   // scan end 1 ms, sent at 3.5 ms: 2500 µs to the nearest 8 µs step
  EXPECT_EQ(da.state, ipc::WireState::kTracking);
  EXPECT_EQ(ch.last_t_ns(), 3'500'000);
  EXPECT_EQ(sink.counters().poses_sent.load(), 1u);
}

TEST(CanPoseSink, FdChannelSendsOne64BytePoseFrame) {
  hal::MemoryCanChannel ch(64, /*fd=*/true);
  co::CanPoseSink sink(ch, {});
  ASSERT_TRUE(sink.fd());
  ASSERT_EQ(sink.publish(pose(2, 70000), 2'000'000), pl::PublishResult::kSent);
  ASSERT_EQ(ch.sent_count(), 1u);
  const auto& f = ch.sent(0);
  EXPECT_EQ(f.id, 0x122u);
  EXPECT_TRUE(f.fd());
  ipc::PoseFd d;
  ASSERT_TRUE(ipc::decode_pose_fd(f.data, f.len, d));
  EXPECT_EQ(d.seq, 70000u);  // full 32-bit counter in FD
  EXPECT_EQ(d.target, 2);
  EXPECT_EQ(d.scale_pm_per_px, 40000u);
}

// CAN's age runs from when the beam passed the target (PoseRecord::t_beam_ns), the time the pose
// is valid for: a full-field search frame's pose is tens of ms older than its scan's end. The
// classic frame's age (8 µs steps) saturates; the FD frame's carries it whole. (Base: age from the
// scan's end, 2500 µs here.)
TEST(CanPoseSink, AgeRunsFromWhenTheBeamPassedTheTarget) {
  auto p = pose(0, 5);
  p.t_scan_end_ns = 80'000'000;
  p.t_beam_ns = 41'000'000;  // the target's rows scanned 39 ms before the field scan ended
  hal::MemoryCanChannel classic;
  co::CanPoseSink cs(classic, {});
  ASSERT_EQ(cs.publish(p, 82'500'000), pl::PublishResult::kSent);
  ipc::PoseAttr da;
  ASSERT_TRUE(ipc::decode_pose_attr(classic.sent(1).data, classic.sent(1).len, da));
  EXPECT_EQ(da.age_us, 32760) << "41.5 ms: saturated";
  hal::MemoryCanChannel fd(64, /*fd=*/true);
  co::CanPoseSink fs(fd, {});
  ASSERT_EQ(fs.publish(p, 82'500'000), pl::PublishResult::kSent);
  ipc::PoseFd d;
  ASSERT_TRUE(ipc::decode_pose_fd(fd.sent(0).data, fd.sent(0).len, d));
  EXPECT_EQ(d.age_us, 41500u);
  p.t_beam_ns = 79'000'000;  // an ROI frame's target about mid-scan
  ASSERT_EQ(cs.publish(p, 82'500'000), pl::PublishResult::kSent);
  ASSERT_TRUE(ipc::decode_pose_attr(classic.sent(4).data, classic.sent(4).len, da));
  EXPECT_EQ(da.age_us, 3504);
}

// A pose of a two-fold symmetric target (a lamella) says so on the bus, classic and FD: its φ
// is known modulo 180° (PoseRecord::angle_order from the tracker). Base: not on the wire.
TEST(CanPoseSink, EveryPoseSaysItsAngleOrder) {
  for (std::uint8_t order : {1, 2, 4}) {
    auto p = pose(1, 7);
    p.angle_order = order;
    hal::MemoryCanChannel classic;
    co::CanPoseSink cs(classic, {});
    ASSERT_EQ(cs.publish(p, 3'500'000), pl::PublishResult::kSent);
    ipc::PoseAttr da;
    ASSERT_TRUE(ipc::decode_pose_attr(classic.sent(1).data, classic.sent(1).len, da));
    EXPECT_EQ(da.angle_order, order);
    hal::MemoryCanChannel fd(64, /*fd=*/true);
    co::CanPoseSink fs(fd, {});
    ASSERT_EQ(fs.publish(p, 3'500'000), pl::PublishResult::kSent);
    ipc::PoseFd d;
    ASSERT_TRUE(ipc::decode_pose_fd(fd.sent(0).data, fd.sent(0).len, d));
    EXPECT_EQ(d.angle_order, order);
  }
}

TEST(CanPoseSink, NonFinitePoseIsSentAsLostBadFrame) {
  hal::MemoryCanChannel ch;
  co::CanPoseSink sink(ch, {});
  auto p = pose(0, 1);
  p.x_px = std::numeric_limits<double>::quiet_NaN();
  sink.publish(p, 2'000'000);
  ipc::PoseAttr da;
  ipc::decode_pose_attr(ch.sent(1).data, 8, da);
  EXPECT_EQ(da.state, ipc::WireState::kLost);
  EXPECT_TRUE(da.reason_bits & sempose::pose::kReasonBadFrame);
}

// A position POSE_XY cannot carry (±134 mm) saturates: never TRACKING (hostile round 11: with
// nm_per_px 1e6 every pose went out pinned at 134217727 nm, TRACKING).
TEST(CanPoseSink, APositionBeyondTheWiresRangeIsNotTracking) {
  hal::MemoryCanChannel ch;
  co::CanPoseSink sink(ch, {});
  auto p = pose(0, 1);
  p.nm_per_px = 1e6;  // 101 px -> 101 mm: fits
  sink.publish(p, 2'000'000);
  ipc::PoseAttr da;
  ipc::decode_pose_attr(ch.sent(1).data, 8, da);
  EXPECT_EQ(da.state, ipc::WireState::kTracking);
  p.x_px = 200.0;  // 200 mm: beyond
  sink.publish(p, 3'000'000);
  ipc::decode_pose_attr(ch.sent(4).data, 8, da);
  EXPECT_EQ(da.state, ipc::WireState::kUncertain);
  EXPECT_TRUE(da.reason_bits & sempose::pose::kReasonOutOfField);
}

TEST(CanPoseSink, DroppedFramesAreCountedAndNeverBlock) {
  hal::MemoryCanChannel ch;
  co::CanPoseSink sink(ch, {});
  ch.set_fail_sends(true);
  EXPECT_EQ(sink.publish(pose(0, 1), 2'000'000), pl::PublishResult::kDropped);
  EXPECT_EQ(sink.counters().poses_dropped.load(), 1u);
  EXPECT_EQ(ch.counters().tx_dropped.load(), 1u) << "ATTR is not sent when XY was dropped";
  EXPECT_EQ(sink.publish(pose(7, 1), 2'000'000), pl::PublishResult::kError) << "target outside 0..3";
}

TEST(CanPoseSink, HeartbeatAtAFixedRateWithStatus) {
  hal::MemoryCanChannel ch;
  co::CanSinkOptions o;
  o.heartbeat_period_ns = 100'000'000;  // 10 Hz
  co::CanPoseSink sink(ch, o);
  pl::PipelineStatus s;
  s.state = sempose::pose::TrackState::kLost;
  s.pattern_set = 2;
  s.dwell_ns = 300;
  s.dropped_frames = 258;
  s.overruns = 5;
  ch.set_bus_state(hal::CanBusState::kPassive);
  // 1 s of 1 kHz service calls -> 10 heartbeats, evenly spaced.
  for (std::int64_t t = 0; t < 1'000'000'000; t += 1'000'000) sink.service(s, t);
  ASSERT_EQ(ch.sent_count(), 10u);
  for (std::size_t i = 0; i < ch.sent_count(); ++i) {
    ipc::Heartbeat h;
    ASSERT_EQ(ch.sent(i).id, 0x140u);
    ASSERT_TRUE(ipc::decode_heartbeat(ch.sent(i).data, ch.sent(i).len, h));
    EXPECT_EQ(h.counter, i);
    EXPECT_EQ(h.state, ipc::WireState::kLost);
    EXPECT_EQ(h.bus_state, ipc::BusState::kPassive);
    EXPECT_EQ(h.pattern_set, 2);
    EXPECT_EQ(h.dwell_ns, 300);
    EXPECT_EQ(h.dropped_frames, 258 % 256);
    EXPECT_EQ(h.overruns, 5);
  }
  // A stall of 2 s does not produce a burst of 20 catch-up heartbeats.
  ch.clear_sent();
  sink.service(s, 3'000'000'000);
  sink.service(s, 3'001'000'000);
  EXPECT_EQ(ch.sent_count(), 1u);
  EXPECT_EQ(sink.counters().heartbeats_sent.load(), 11u);
}

TEST(CanPoseSink, ValidCommandsAreHandedOutInOrder) {
  hal::MemoryCanChannel ch;
  co::CanPoseSink sink(ch, {});
  ch.inject(command(0x150, {1, 10, 3, 0, 0x28, 0x9A, 0, 0}));  // select set 3, 39.464 nm/px
  ch.inject(command(0x150, {4, 11, 0xFF, 0, 0, 0, 0, 0}));     // re-acquire all
  ch.inject(command(0x150, {3, 12, 0, 0, 0, 0, 0, 0}));        // stop
  sink.service({}, 0);
  pl::Command c;
  ASSERT_TRUE(sink.next_command(c));
  EXPECT_EQ(c.kind, pl::CommandKind::kSelectPatternSet);
  EXPECT_EQ(c.arg, 3);
  EXPECT_DOUBLE_EQ(c.nm_per_px, 39.464);
  ASSERT_TRUE(sink.next_command(c));
  EXPECT_EQ(c.kind, pl::CommandKind::kReacquire);
  EXPECT_EQ(c.target, 0xFF);
  ASSERT_TRUE(sink.next_command(c));
  EXPECT_EQ(c.kind, pl::CommandKind::kStop);
  EXPECT_FALSE(sink.next_command(c));
  EXPECT_EQ(sink.counters().commands_accepted.load(), 3u);
  EXPECT_EQ(sink.counters().last_command_seq.load(), 12);
  // Received is not applied: the heartbeat echoes only what the pipeline reports as taken
  // effect, never a seq the sink merely decoded.
  ipc::Heartbeat h;
  ipc::decode_heartbeat(ch.sent(0).data, 8, h);
  EXPECT_EQ(h.last_command_seq, 0);
  EXPECT_EQ(c.seq, 12);
  pl::PipelineStatus applied;
  applied.last_command_seq = 12;
  applied.commands_rejected = 2;
  sink.service(applied, 1'000'000'000);  // past the heartbeat period
  ASSERT_GE(ch.sent_count(), 2u);
  ipc::decode_heartbeat(ch.sent(ch.sent_count() - 1).data, 8, h);
  EXPECT_EQ(h.last_command_seq, 12);
  EXPECT_EQ(h.bad_commands, 2) << "refused commands are reported with the malformed ones";
}

TEST(CanPoseSink, BadCommandsAreCountedAndNeverActedOn) {
  hal::MemoryCanChannel ch;
  co::CanPoseSink sink(ch, {});
  ch.inject(command(0x150, {2, 1, 0, 0, 0, 0, 0}));            // DLC 7
  ch.inject(command(0x150, {9, 2, 0, 0, 0, 0, 0, 0}));         // unknown opcode
  ch.inject(command(0x150, {1, 3, 99, 0, 0, 0, 0, 0}));        // pattern set 99
  ch.inject(command(0x150, {4, 4, 7, 0, 0, 0, 0, 0}));         // target 7
  auto rtr = command(0x150, {});
  rtr.flags = hal::CanFrame::kRemote;
  rtr.len = 8;
  ch.inject(rtr);                                              // remote frame
  auto ext = command(0x150, {2, 6, 0, 0, 0, 0, 0, 0});
  ext.flags = hal::CanFrame::kExtended;
  ch.inject(ext);                                              // extended frame on the command id
  auto fd = command(0x150, {2, 7, 0, 0, 0, 0, 0, 0});
  fd.flags = hal::CanFrame::kFd;
  ch.inject(fd);                                               // FD frame on the command id
  ch.inject(command(0x7FF, {2, 5, 0, 0, 0, 0, 0, 0}));         // someone else's id: ignored, not bad
  sink.service({}, 0);
  pl::Command c;
  EXPECT_FALSE(sink.next_command(c));
  EXPECT_EQ(sink.counters().bad_commands.load(), 7u);
  EXPECT_EQ(sink.counters().non_command_frames.load(), 1u);
  EXPECT_EQ(sink.counters().commands_accepted.load(), 0u);
  ipc::Heartbeat h;
  ipc::decode_heartbeat(ch.sent(0).data, 8, h);
  EXPECT_EQ(h.bad_commands, 7);
}

TEST(CanPoseSink, CommandsPerCycleAreBounded) {
  hal::MemoryCanChannel ch;
  co::CanSinkOptions o;
  o.max_commands_per_cycle = 2;
  co::CanPoseSink sink(ch, o);
  for (int i = 0; i < 5; ++i) ch.inject(command(0x150, {2, static_cast<std::uint8_t>(i), 0, 0, 0, 0, 0, 0}));
  sink.service({}, 0);
  EXPECT_EQ(sink.counters().commands_accepted.load(), 2u);
  sink.service({}, 1);
  sink.service({}, 2);
  EXPECT_EQ(sink.counters().commands_accepted.load(), 5u);
}

TEST(CanPoseSink, RtPathDoesNotAllocate) {
  hal::MemoryCanChannel ch(8192);
  co::CanPoseSink sink(ch, {});
  for (int i = 0; i < 50; ++i) ch.inject(command(0x150, {2, static_cast<std::uint8_t>(i), 0, 0, 0, 0, 0, 0}));
  pl::PipelineStatus s;
  pl::Command c;
  int commands = 0;
  {
    sempose::rt::alloc::ScopedArm arm;
    for (std::uint32_t i = 0; i < 1000; ++i) {
      sink.publish(pose(static_cast<std::uint8_t>(i % 4), i), i * 1'000'000ll);
      sink.service(s, i * 1'000'000ll);
      while (sink.next_command(c)) ++commands;
    }
    EXPECT_EQ(sempose::rt::alloc::this_thread_allocations(), 0u);
  }
  EXPECT_EQ(commands, 50);
  EXPECT_EQ(sink.counters().poses_sent.load(), 1000u);
}
