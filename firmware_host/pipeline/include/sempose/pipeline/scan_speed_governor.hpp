// Adaptive scan-speed governor (pure algorithm, no I/O, no clock; PX4 style). Picks the pixel
// dwell of the next ROI so that its scan time ≈ the robust recent compute time per pose ×
// (1 + margin): the beam and the CPU are both busy and the image is as clean as the compute
// time allows. When match quality falls it lengthens the dwell further, but never so far
// that a target's pose rate drops below min_pose_rate_hz. RT-safe after construction.
//
// Robust compute estimate: the `percentile` of the last `window` compute times, taken at
// once when it rises (an overrun costs a frame) and followed by an EWMA when it falls.
// Hysteresis: a longer dwell is taken immediately; a shorter one only once the wanted dwell
// is more than `hysteresis` below the current one, then approached at most
// `max_decrease_per_frame` per pose, so noise inside the band never moves the dwell.
#pragma once

#include <array>
#include <cstdint>

#include "sempose/config/governor_config.hpp"
#include "sempose/hal/frame.hpp"
#include "sempose/hal/scan_source.hpp"

namespace sempose::pipeline {

class ScanSpeedGovernor {
 public:
  static constexpr std::size_t kMaxWindow = 64;

  // Setup. limits: the scan generator's dwell range, step and flyback; target_count >= 1.
  ScanSpeedGovernor(const config::GovernorConfig& config, const hal::ScanLimits& limits,
                    int target_count) noexcept;

  // After each pose of `target`: its compute time and match quality. Compute times of
  // non-tracking poses (full-field start search) are not representative and are ignored.
  void observe(std::uint8_t target, std::int64_t compute_ns, float score, float psr,
               bool tracking) noexcept;
  // After a ROI pose of `target` the tracker reported LOST: its score says little (the tracker
  // judges it against its own levels, not the governor's low_score), the state says the dwell
  // did not carry the target. The next ROIs get quality_gain more dwell (up to the cap), as a
  // low-quality pose does. Without it a governor that had reached a 100 ns floor stayed there
  // through LOST ROI frames (a needle spinning at 30°/s, 3 e-/px: LOST ROI frame, 500 ns start
  // search, LOST ROI frame at 100 ns again, ... half the frames slow full-field searches).
  void lost_on_roi(std::uint8_t target) noexcept;

  // The shortest dwell `target`'s poses can use (its tracker's shortest_correctable_dwell_ns:
  // a slow detector's lag beyond what sempose corrects makes every pose UNCERTAIN below it). ROI
  // dwells stay at or above it, short of the min_pose_rate_hz cap; 0: none.
  void set_dwell_floor(std::uint8_t target, std::uint32_t floor_ns) noexcept {
    targets_[clamp_target(target)].dwell_floor_ns = floor_ns;
  }

  // Dwell for the next w×h ROI of `target` (updates that target's hysteresis state).
  std::uint32_t next_dwell_ns(std::uint8_t target, std::int32_t w, std::int32_t h) noexcept;

  // Dwell for the next scan of `target`: a full-field scan (start search) gets the initial
  // dwell and leaves the ROI hysteresis alone; a ROI gets next_dwell_ns. The one rule the RT
  // pipeline and the offline runner share.
  std::uint32_t dwell_for_scan(std::uint8_t target, std::int32_t w, std::int32_t h, bool full_field) noexcept {
    return full_field ? initial_dwell_ns() : next_dwell_ns(target, w, h);
  }

  // The dwell the estimate alone asks for, before hysteresis (for tests and plots).
  std::uint32_t wanted_dwell_ns(std::uint8_t target, std::int32_t w, std::int32_t h) const noexcept;

  std::int64_t compute_estimate_ns() const noexcept { return estimate_ns_; }
  double quality_factor(std::uint8_t target) const noexcept { return targets_[clamp_target(target)].quality; }
  // governor.initial_dwell_ns on the generator's step inside the governor's range: the first
  // ROI's dwell, and every full-field (start search) scan's.
  std::uint32_t initial_dwell_ns() const noexcept { return quantize_up(static_cast<double>(config_.initial_dwell_ns)); }
  std::uint32_t min_dwell_ns() const noexcept { return min_dwell_ns_; }
  std::uint32_t max_dwell_ns() const noexcept { return max_dwell_ns_; }

 private:
  struct TargetState {
    double quality = 1.0;           // >= 1: dwell lengthening for poor match quality
    std::uint32_t dwell_ns = 0;     // current commanded dwell (0: none yet)
    bool decreasing = false;        // left the hysteresis band downward; approaching
    std::uint32_t dwell_floor_ns = 0;  // set_dwell_floor (0: none)
  };
  std::size_t clamp_target(std::uint8_t t) const noexcept {
    return t < static_cast<std::uint8_t>(target_count_) ? t : 0;
  }
  std::uint32_t quantize_up(double dwell_ns) const noexcept;
  std::uint32_t quantize_down(double dwell_ns) const noexcept;
  std::int64_t window_percentile() const noexcept;

  config::GovernorConfig config_;
  std::uint32_t min_dwell_ns_;
  std::uint32_t max_dwell_ns_;
  std::uint32_t step_ns_;
  std::uint32_t flyback_ns_;
  int target_count_;
  std::array<std::int64_t, kMaxWindow> window_{};
  std::size_t window_size_;
  std::size_t window_fill_ = 0;
  std::size_t window_next_ = 0;
  std::int64_t estimate_ns_ = 0;  // 0: nothing observed yet
  std::array<TargetState, hal::kMaxTargets> targets_{};
};

}  // namespace sempose::pipeline
