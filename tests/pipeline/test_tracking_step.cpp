// TrackingStep's same-place rule on real trackers and the simulated SEM. Two targets share
// a pattern; target 1 follows its own needle, which walks smoothly onto the place target 0
// holds. At most one of two look-alike targets on one place can be right and the pixels
// cannot say which, so target 1's poses there must be UNCERTAIN and flagged look_alike, and
// after kSamePlaceFrames of them its tracker must search again with the search's frame
// flagged (so a controller tells it from a REACQUIRE of its own). Each target is scanned on
// its own simulated scene (one needle each): the crossing's other rules (a declined jump, a
// rival) cannot step in, and the rule is the only thing that can flag these poses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "sempose/config/app_config.hpp"
#include "sempose/hal/source_factory.hpp"
#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pipeline/stage_clock.hpp"
#include "sempose/pipeline/tracker_setup.hpp"
#include "sempose/pipeline/tracking_step.hpp"
#include "sempose/pose/tracker.hpp"

namespace sempose::pipeline {
namespace {

constexpr double kPlaceX = 512, kPlaceY = 384;  // the needle target 0 holds
constexpr double kApproachPx = 50;              // target 1's needle starts this far left of it
constexpr double kSpeedPxS = 20;                // and walks right at this speed

config::AppConfig base() {
  config::AppConfig cfg;
  std::string errors;
  const std::string yaml = std::string(SEMPOSE_SOURCE_DIR) + "/tests/pipeline/pipeline_virtual.yaml";
  EXPECT_TRUE(config::load_app_config(yaml, cfg, errors)) << errors;
  EXPECT_FALSE(cfg.sim.targets.empty());
  cfg.sim.targets.resize(1);  // the default scene's needle tip (the gripper beside it is off)
  cfg.sim.targets[0].trajectory = {};  // standing still
  return cfg;
}

// Scene `who` (0 or 1): only that target's needle; 2: both standing apart (the patterns'
// recording, so both trackers get the same pattern, as an operator records identical tools).
config::AppConfig scene(int who) {
  config::AppConfig cfg = base();
  cfg.sim.targets.push_back(cfg.sim.targets.front());
  auto& a = cfg.sim.targets[0];
  auto& b = cfg.sim.targets[1];
  a.x_px = kPlaceX, a.y_px = kPlaceY;
  b.x_px = kPlaceX - kApproachPx, b.y_px = kPlaceY;
  if (who == 2) b.x_px = kPlaceX - 300;
  if (who == 1) b.trajectory.kind = "linear", b.trajectory.vx_px_s = kSpeedPxS;
  a.enabled = who != 1;
  b.enabled = who != 0;
  return cfg;
}

struct Scanner {  // one scene's source and a slot to scan into
  std::unique_ptr<hal::ScanSource> source;
  hal::FramePool pool;
  explicit Scanner(const config::AppConfig& cfg)
      : source(make(cfg)), pool(1, frame_slot_pixels(source->limits())) {}
  static std::unique_ptr<hal::ScanSource> make(const config::AppConfig& cfg) {
    rt::Status st;
    auto s = hal::make_scan_source(cfg.source, cfg.scan, cfg.sim, cfg.replay, st);
    EXPECT_TRUE(s) << st.message;
    return s;
  }
  hal::FrameSlot& scan(const hal::ScanRequest& req) {
    hal::FrameSlot& slot = pool[0];
    EXPECT_EQ(source->start(req, slot), hal::StartResult::kStarted);
    EXPECT_EQ(source->poll(), hal::PollResult::kDone);  // the virtual clock completes at once
    return slot;
  }
};

TEST(TrackingStep, TwoLookAlikeTargetsOnOnePlaceAreUncertainThenTheArrivingOneSearches) {
  const config::AppConfig recording = scene(2);
  Scanner both(recording), still(scene(0)), walking(scene(1));
  TrackerSetup setup;
  ASSERT_TRUE(make_trackers(recording, both.source->limits(), setup).ok);
  ASSERT_EQ(setup.trackers.size(), 2u);
  std::vector<pose::Tracker*> raw{setup.trackers[0].get(), setup.trackers[1].get()};
  const std::unique_ptr<StageClock> clock = make_stage_clock(recording);
  TrackingStep step(recording.governor, both.source->limits(), raw, *clock);

  auto track = [&](Scanner& s, std::uint8_t target) {
    hal::FrameSlot& slot = s.scan(step.next_scan(target));
    slot.meta.t_seen_ns = slot.meta.t_scan_end_ns;
    return step.track(slot.meta, slot.pixels).est;
  };
  // Both acquired while apart (a start search skips places a look-alike holds, pattern / 4 around).
  int tracking0 = 0;
  for (int i = 0; i < 10; ++i) tracking0 += track(still, 0).state == pose::TrackState::kTracking;
  int tracking1 = 0;
  for (int i = 0; i < 10; ++i) tracking1 += track(walking, 1).state == pose::TrackState::kTracking;
  ASSERT_GE(tracking0, 5);
  ASSERT_GE(tracking1, 5);

  // Walk on, target 0 scanned between target 1's frames, until target 1's needle is well past.
  int flagged_uncertain = 0, flagged_tracking = 0, own_searches = 0, in_a_row = 0;
  for (int i = 0; i < 600; ++i) {
    const pose::PoseEstimate e0 = track(still, 0);
    const pose::PoseEstimate e1 = track(walking, 1);
    EXPECT_TRUE(e0.state != pose::TrackState::kTracking || std::abs(e0.x_px - kPlaceX) < 3) << "frame " << i;
    if (!e1.look_alike) {
      in_a_row = 0;
      continue;
    }
    if (e1.followed && e1.state == pose::TrackState::kUncertain && !e1.searched) {
      ++flagged_uncertain;
      ++in_a_row;
      continue;
    }
    if (e1.state == pose::TrackState::kTracking) ++flagged_tracking;
    // Not a same-place pose: the frame of the search the step started, after 3 in a row.
    ++own_searches;
    EXPECT_GE(in_a_row, 3) << "frame " << i << ": a search flagged look_alike after " << in_a_row;
    in_a_row = 0;
  }
  std::printf("target 1 on target 0's place: %d UNCERTAIN look_alike, %d own searches\n", flagged_uncertain, own_searches);
  EXPECT_GE(flagged_uncertain, 3);
  EXPECT_GE(own_searches, 1);
  EXPECT_EQ(flagged_tracking, 0);
}

// A target standing still stays TRACKING while the governor shortens its dwell: its score falls
// with the dwell (0.81 at 500 ns, 0.69 at 250 ns), which the static-clutter rule (a fall while
// the pose stands still) took for the target leaving its pattern's clutter: before its levels
// were carried to the frame's dwell, `sempose run` on this scene was TRACKING on 1 pose of 3033.
TEST(TrackingStep, AStillTargetStaysTrackingWhileTheGovernorShortensItsDwell) {
  const config::AppConfig cfg = scene(0);
  Scanner still(cfg);
  TrackerSetup setup;
  ASSERT_TRUE(make_trackers(cfg, still.source->limits(), setup).ok);
  ASSERT_EQ(setup.trackers.size(), 1u);
  const std::unique_ptr<StageClock> clock = make_stage_clock(cfg);
  TrackingStep step(cfg.governor, still.source->limits(), {setup.trackers[0].get()}, *clock);
  int tracking = 0, frames = 0;
  std::uint32_t first_dwell = 0, shortest = ~0u;
  for (int i = 0; i < 400; ++i) {
    hal::FrameSlot& slot = still.scan(step.next_scan(0));
    slot.meta.t_seen_ns = slot.meta.t_scan_end_ns;
    const pose::PoseEstimate e = step.track(slot.meta, slot.pixels).est;
    if (e.searched) continue;
    if (first_dwell == 0) first_dwell = slot.meta.dwell_ns;
    shortest = std::min(shortest, slot.meta.dwell_ns);
    ++frames;
    tracking += e.state == pose::TrackState::kTracking;
    EXPECT_TRUE(e.state != pose::TrackState::kTracking || std::hypot(e.x_px - kPlaceX, e.y_px - kPlaceY) < 3) << i;
  }
  std::printf("still needle: %d of %d ROI frames TRACKING, dwell %u -> %u ns\n", tracking, frames, first_dwell, shortest);
  ASSERT_LT(shortest, first_dwell) << "the governor kept the dwell: the case is not exercised";
  EXPECT_GE(tracking, frames * 95 / 100);
}

// A slow detector (sim.detector_tau_ns 1000: 4 px of lag at 250 ns, 9.5 px at the governor's
// 100 ns floor). The governor shortened the dwell to 100 ns, where the lag is beyond what sempose
// corrects and every pose UNCERTAIN (afe0cba: 0.2 % TRACKING in `sempose run`); the tracker's
// shortest correctable dwell now floors the ROI dwell. Told τ right (the simulator's, as setup
// tells it), and told 1 px while the frames lag 4 (the frames' measured τ used): both follow.
TEST(TrackingStep, ASlowDetectorKeepsTheDwellWhereItsLagIsCorrected) {
  for (const double told_tau_ns : {0.0, 250.0}) {
    config::AppConfig cfg = scene(0);
    cfg.scan.min_dwell_ns = 100;  // the generator's shortest, which the governor goes to here
    cfg.sim.detector_tau_ns = 1000;
    cfg.tracker.detector_tau_ns = told_tau_ns;
    Scanner still(cfg);
    TrackerSetup setup;
    ASSERT_TRUE(make_trackers(cfg, still.source->limits(), setup).ok);
    const std::unique_ptr<StageClock> clock = make_stage_clock(cfg);
    TrackingStep step(cfg.governor, still.source->limits(), {setup.trackers[0].get()}, *clock);
    int tracking = 0, frames = 0, off = 0;
    std::uint32_t shortest = ~0u;
    for (int i = 0; i < 400; ++i) {
      hal::FrameSlot& slot = still.scan(step.next_scan(0));
      slot.meta.t_seen_ns = slot.meta.t_scan_end_ns;
      const pose::PoseEstimate e = step.track(slot.meta, slot.pixels).est;
      if (e.searched || i < 100) continue;  // from the 100th frame: the floor settled
      shortest = std::min(shortest, slot.meta.dwell_ns);
      ++frames;
      tracking += e.state == pose::TrackState::kTracking;
      off += e.state == pose::TrackState::kTracking && std::hypot(e.x_px - kPlaceX, e.y_px - kPlaceY) >= 3;
    }
    const std::uint32_t floor_ns = setup.trackers[0]->shortest_correctable_dwell_ns();
    std::printf("slow detector, told %.0f ns: %d of %d ROI frames TRACKING (%d > 3 px off), shortest dwell %u ns, floor %u ns\n",
                told_tau_ns, tracking, frames, off, shortest, floor_ns);
    EXPECT_GT(floor_ns, 150u) << "τ 1000 ns: lag 3.6 px at ~236 ns";
    EXPECT_LT(floor_ns, 400u);
    EXPECT_GE(shortest, floor_ns) << "a ROI scanned below the detector's floor";
    EXPECT_GE(tracking, frames * 9 / 10) << "told " << told_tau_ns;
    EXPECT_EQ(off, 0);
  }
}

}  // namespace
}  // namespace sempose::pipeline
