// Optional temporal filter of the pose stream: per axis (x, y, φ) a Kalman filter with a
// constant-acceleration model (position, velocity, acceleration) driven by continuous white
// jerk, on the real frame timestamps (the scan-speed governor varies the frame interval).
// An innovation gate re-initialises the filter from the measurement when the motion breaks
// the model (bounce, jump, torn frame), so it never smooths a real jump away; right after a
// (re)start it outputs the raw poses and converges over a few frames. When the motion is
// faster than the configured jerk (lag shows as oversized innovations) the process noise of
// that axis is raised until the innovations fit again (adapt_jerk).
//
// Pure algorithm, RT-safe: update() and reset() are noexcept, allocate nothing, block on
// nothing. The constructor checks the settings (setup only; throws std::invalid_argument).
#pragma once

#include <array>
#include <cstdint>

#include "sempose/config/pose_filter_config.hpp"

namespace sempose::pose {

struct PoseSample {
  double t_s = 0.0;      // frame time, seconds on any monotonic clock (e.g. scan end)
  double x_px = 0.0;
  double y_px = 0.0;
  double phi_deg = 0.0;  // (-180, 180]
};

// What the last update() did (for counters and logs).
enum class PoseFilterEvent : std::uint8_t {
  kDisabled,      // config.enabled == false: the input passed through
  kStarted,       // first sample after construction/reset(): output = input
  kFiltered,      // normal filtered output
  kGateReset,     // innovation beyond gate_sigma: re-initialised, output = input
  kGapReset,      // dt <= 0 or dt > max_gap_s: re-initialised, output = input
  kInvalidInput,  // a non-finite field: filter reset, the input passed through unchanged
};

const char* to_string(PoseFilterEvent event) noexcept;

class PoseFilter {
 public:
  explicit PoseFilter(const config::PoseFilterConfig& config);

  // Forget the state (the tracker (re)acquires); the next update() starts afresh.
  void reset() noexcept;
  // Filter one measured pose. Finite input gives finite output, always.
  PoseSample update(const PoseSample& measured) noexcept;

  bool last_was_outlier() const noexcept { return last_event_ == PoseFilterEvent::kGateReset; }
  PoseFilterEvent last_event() const noexcept { return last_event_; }
  const config::PoseFilterConfig& config() const noexcept { return config_; }

  // One axis' state (exposed for tests and for the tracker's diagnostics).
  struct AxisState {
    std::array<double, 3> x{};                     // position, velocity, acceleration
    std::array<std::array<double, 3>, 3> P{};      // covariance
  };
  const AxisState& axis(int i) const noexcept { return axes_[static_cast<std::size_t>(i)]; }
  // Current process-noise factor of an axis (1 = the configured jerk; > 1 = raised because
  // the motion outran the model, see PoseFilterConfig::adapt_jerk).
  double process_noise_scale(int i) const noexcept { return noise_scale_[static_cast<std::size_t>(i)]; }

 private:
  PoseSample start_from(const PoseSample& measured, PoseFilterEvent event) noexcept;

  config::PoseFilterConfig config_;
  std::array<double, 3> meas_var_{};   // r² per axis
  std::array<double, 3> jerk_psd_{};   // q per axis
  std::array<AxisState, 3> axes_{};
  std::array<double, 3> noise_scale_{};  // adaptive factor on jerk_psd_
  std::array<double, 3> nis_average_{};  // EWMA of the squared normalized innovation
  double last_t_s_ = 0.0;
  bool started_ = false;
  PoseFilterEvent last_event_ = PoseFilterEvent::kStarted;
};

}  // namespace sempose::pose
