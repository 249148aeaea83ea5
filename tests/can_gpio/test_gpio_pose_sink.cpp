// GpioPoseSink: pose-valid follows TRACKING of every target, heartbeat toggles per pose.
#include <gtest/gtest.h>

#include "sempose/can_output/gpio_pose_sink.hpp"

namespace co = sempose::can_output;
namespace pl = sempose::pipeline;
using sempose::pose::TrackState;

namespace {

struct FakeOutputs final : sempose::hal::StatusOutputs {
  bool valid = false;
  int heartbeat = 0;
  int toggles = 0;
  void set_pose_valid(bool v) noexcept override { valid = v; }
  void toggle_heartbeat() noexcept override {
    heartbeat ^= 1;
    ++toggles;
  }
};

struct CountingSink final : pl::PoseSink {
  int published = 0;
  int serviced = 0;
  pl::PublishResult publish(const pl::PoseRecord&, std::int64_t) noexcept override {
    ++published;
    return pl::PublishResult::kSent;
  }
  void service(const pl::PipelineStatus&, std::int64_t) noexcept override { ++serviced; }
};

pl::PoseRecord pose(std::uint8_t target, TrackState s) {
  pl::PoseRecord p;
  p.target = target;
  p.state = s;
  return p;
}

}  // namespace

TEST(GpioPoseSink, PoseValidWhileEveryTargetTracks) {
  CountingSink inner;
  FakeOutputs out;
  co::GpioPoseSink sink(inner, out);
  sink.publish(pose(0, TrackState::kAcquiring), 0);
  EXPECT_FALSE(out.valid);
  sink.publish(pose(0, TrackState::kTracking), 0);
  EXPECT_TRUE(out.valid);
  sink.publish(pose(1, TrackState::kAcquiring), 0);
  EXPECT_FALSE(out.valid) << "a second target not tracking yet";
  sink.publish(pose(1, TrackState::kTracking), 0);
  EXPECT_TRUE(out.valid);
  sink.publish(pose(0, TrackState::kLost), 0);
  EXPECT_FALSE(out.valid);
  EXPECT_EQ(out.toggles, 5);
  EXPECT_EQ(inner.published, 5);
}

TEST(GpioPoseSink, StopDropsPoseValid) {
  CountingSink inner;
  FakeOutputs out;
  co::GpioPoseSink sink(inner, out);
  sink.publish(pose(0, TrackState::kTracking), 0);
  ASSERT_TRUE(out.valid);
  pl::PipelineStatus s;
  s.running = false;
  sink.service(s, 0);
  EXPECT_FALSE(out.valid);
  EXPECT_EQ(inner.serviced, 1);
  sink.publish(pose(0, TrackState::kTracking), 0);
  EXPECT_FALSE(out.valid) << "stopped: no valid pose even if the tracker still says TRACKING";
}
