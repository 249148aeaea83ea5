// One frame through its target's tracker, written once for the RT pipeline's correlation
// stage and the offline runner: time stamps from the stage clock, the governor fed, the
// target's next scan planned by the governor's rule, the pose record numbered per target.
// RT-safe after construction: noexcept, no allocation.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "sempose/config/governor_config.hpp"
#include "sempose/hal/frame.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/pipeline/pose_sink.hpp"
#include "sempose/pipeline/scan_speed_governor.hpp"
#include "sempose/pipeline/stage_clock.hpp"
#include "sempose/pose/tracker.hpp"

namespace sempose::pipeline {

class TrackingStep {
 public:
  struct Outcome {
    pose::PoseEstimate est;
    std::uint8_t target = 0;
    std::int64_t t_start_ns = 0;         // when tracking of the frame started (stage clock)
    std::int64_t compute_ns = 0;         // as the clock accounts it (modelled or measured)
    std::int64_t prev_pose_done_ns = 0;  // the pose before this one (0: none yet)
  };

  // trackers[i] tracks target i (not null; the caller checks); they and clock outlive the step.
  TrackingStep(const config::GovernorConfig& governor, const hal::ScanLimits& limits,
               std::vector<pose::Tracker*> trackers, const StageClock& clock);

  // Tracks the frame's target on its pixels; sets m.t_pose_done_ns and feeds the governor.
  Outcome track(hal::FrameMeta& m, const hal::Pixel* pixels) noexcept;
  // The target's next scan: its tracker's next ROI, the full field's dwell for a start search
  // or the governor's for a ROI. Call once per pose, right after it (the governor's ROI
  // hysteresis advances per call).
  hal::ScanRequest next_scan(std::uint8_t target) noexcept;
  // The pose as it leaves for the sinks, numbered per target. nm_per_px: the active scale.
  PoseRecord record(const hal::FrameMeta& m, const Outcome& o, double nm_per_px) noexcept;

 private:
  const StageClock& clock_;
  hal::ScanLimits limits_;
  std::vector<pose::Tracker*> trackers_;
  ScanSpeedGovernor governor_;
  std::int64_t prev_pose_done_ns_ = 0;
  std::array<std::uint32_t, hal::kMaxTargets> pose_seq_{};
  // Where each target is followed: a start search of a look-alike target does not take that
  // object (several targets may share a pattern).
  struct Held {
    bool held = false;
    double x_px = 0, y_px = 0;
    // Where it was seen (mid-scan) and how fast it moved since its previous held pose: each
    // frame goes to one target, so the others' places are a frame or more old.
    std::int64_t t_ns = 0;
    double vx_px_ns = 0, vy_px_ns = 0;
  };
  std::array<Held, hal::kMaxTargets> held_{};
  // alike_[t][u]: u's patterns look like t's (pose::Tracker::likeness ≥ kAlike, setup).
  std::array<std::array<bool, hal::kMaxTargets>, hal::kMaxTargets> alike_{};
  pose::HeldPlaces held_by_others(std::uint8_t target) const noexcept;
  // Two look-alike targets on one object (they crossed and one followed the other's object):
  // at most one of them can be right, and which one the pixels cannot say. A pose within
  // kSamePlacePx of a place a look-alike target holds is reported UNCERTAIN; after
  // kSamePlaceFrames such frames in a row the target searches the field again, where the
  // start search skips the other's place. The radius is issue 13's false-pose distance: two
  // poses that close belong to objects less than twice it apart, or one of them is false.
  static constexpr double kSamePlacePx = 3.0;
  static constexpr int kSamePlaceFrames = 3;
  bool on_a_look_alikes_place(std::uint8_t target, const pose::PoseEstimate& est, std::int64_t t_ns) const noexcept;
  std::array<int, hal::kMaxTargets> same_place_frames_{};
  // This step asked the target to search again: the frame that runs that search carries
  // look_alike, so a controller tells it (and its reason 32) from a REACQUIRE of its own.
  std::array<bool, hal::kMaxTargets> own_reacquire_{};
};

}  // namespace sempose::pipeline
