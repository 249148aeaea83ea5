#include "sempose/pipeline/scan_speed_governor.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pipeline {

ScanSpeedGovernor::ScanSpeedGovernor(const config::GovernorConfig& config,
                                     const hal::ScanLimits& limits, int target_count) noexcept
    : config_(config),
      min_dwell_ns_(std::max(limits.min_dwell_ns, config.min_dwell_ns)),
      max_dwell_ns_(config.max_dwell_ns == 0 ? limits.max_dwell_ns
                                             : std::min(limits.max_dwell_ns, config.max_dwell_ns)),
      step_ns_(std::max<std::uint32_t>(1, limits.dwell_step_ns)),
      flyback_ns_(limits.line_flyback_ns),
      target_count_(std::clamp(target_count, 1, hal::kMaxTargets)),
      window_size_(std::clamp<std::size_t>(config.window, 1, kMaxWindow)) {
  if (max_dwell_ns_ < min_dwell_ns_) max_dwell_ns_ = min_dwell_ns_;
  // Dwells must be multiples of the step: round the range inward.
  min_dwell_ns_ = (min_dwell_ns_ + step_ns_ - 1) / step_ns_ * step_ns_;
  max_dwell_ns_ = std::max(min_dwell_ns_, max_dwell_ns_ / step_ns_ * step_ns_);
}

std::uint32_t ScanSpeedGovernor::quantize_up(double dwell_ns) const noexcept {
  if (!(dwell_ns > min_dwell_ns_)) return min_dwell_ns_;  // also catches NaN
  if (dwell_ns >= max_dwell_ns_) return max_dwell_ns_;
  const double steps = std::ceil(dwell_ns / step_ns_ - 1e-9);
  return std::clamp(static_cast<std::uint32_t>(steps) * step_ns_, min_dwell_ns_, max_dwell_ns_);
}

std::uint32_t ScanSpeedGovernor::quantize_down(double dwell_ns) const noexcept {
  if (!(dwell_ns > min_dwell_ns_)) return min_dwell_ns_;
  if (dwell_ns >= max_dwell_ns_) return max_dwell_ns_;
  const double steps = std::floor(dwell_ns / step_ns_ + 1e-9);
  return std::clamp(static_cast<std::uint32_t>(steps) * step_ns_, min_dwell_ns_, max_dwell_ns_);
}

std::int64_t ScanSpeedGovernor::window_percentile() const noexcept {
  std::array<std::int64_t, kMaxWindow> sorted{};
  std::copy_n(window_.begin(), window_fill_, sorted.begin());
  const auto n = static_cast<std::ptrdiff_t>(window_fill_);
  auto k = static_cast<std::ptrdiff_t>(std::ceil(config_.percentile * static_cast<double>(n))) - 1;
  k = std::clamp<std::ptrdiff_t>(k, 0, n - 1);
  std::nth_element(sorted.begin(), sorted.begin() + k, sorted.begin() + n);
  return sorted[static_cast<std::size_t>(k)];
}

void ScanSpeedGovernor::observe(std::uint8_t target, std::int64_t compute_ns, float score,
                                float psr, bool tracking) noexcept {
  TargetState& t = targets_[clamp_target(target)];
  if (!tracking) return;  // start search / lost: neither compute nor quality is representative
  if (compute_ns > 0) {
    window_[window_next_] = compute_ns;
    window_next_ = (window_next_ + 1) % window_size_;
    window_fill_ = std::min(window_fill_ + 1, window_size_);
    const std::int64_t p = window_percentile();
    if (estimate_ns_ == 0 || p >= estimate_ns_) {
      estimate_ns_ = p;  // fast attack: a rise costs overruns
    } else {
      estimate_ns_ += static_cast<std::int64_t>(config_.ewma_alpha * static_cast<double>(p - estimate_ns_));
    }
  }
  // Quality with its own hysteresis band: low below the thresholds, good clearly above.
  const bool score_ok = std::isfinite(score);
  const bool low = !score_ok || score < config_.low_score ||
                   (config_.low_psr > 0 && psr < config_.low_psr);
  const bool good = score_ok && score >= config_.low_score + 0.05f &&
                    (config_.low_psr <= 0 || psr >= config_.low_psr * 1.1f);
  if (low) {
    t.quality = std::min(config_.max_quality_factor, t.quality * config_.quality_gain);
  } else if (good) {
    t.quality = std::max(1.0, t.quality / std::sqrt(config_.quality_gain));  // recover slower
  }
}

void ScanSpeedGovernor::lost_on_roi(std::uint8_t target) noexcept {
  TargetState& t = targets_[clamp_target(target)];
  t.quality = std::min(config_.max_quality_factor, t.quality * config_.quality_gain);
}

std::uint32_t ScanSpeedGovernor::wanted_dwell_ns(std::uint8_t target, std::int32_t w,
                                                 std::int32_t h) const noexcept {
  if (!config_.enabled || estimate_ns_ == 0 || w <= 0 || h <= 0) {
    return quantize_up(static_cast<double>(config_.initial_dwell_ns));
  }
  const double pixels = static_cast<double>(w) * h;
  const double flyback = static_cast<double>(h) * flyback_ns_;
  // Compute-matched dwell: scan time ≥ estimate × (1 + margin).
  const double scan_ns = static_cast<double>(estimate_ns_) * (1.0 + config_.margin);
  const double compute_dwell = (scan_ns - flyback) / pixels;
  // Quality lengthening, capped so each target keeps min_pose_rate_hz with every target
  // taking its turn in the schedule.
  const double cycle_budget_ns = 1e9 / config_.min_pose_rate_hz / target_count_;
  const double rate_cap_dwell = (cycle_budget_ns - flyback) / pixels;
  // From the dwell the scan would get without it (the compute-matched one, or the generator's
  // floor when that is longer): lengthening a compute dwell below the floor bought nothing (a
  // 400 us compute on 128² matches 27 ns; 4× that is still under a 100 ns floor).
  const TargetState& t = targets_[clamp_target(target)];
  const double unlengthened = std::max(compute_dwell, static_cast<double>(min_dwell_ns_));
  double dwell = compute_dwell;
  if (t.quality > 1.0) dwell = std::max(compute_dwell, std::min(unlengthened * t.quality, rate_cap_dwell));
  // The detector's floor (set_dwell_floor), within the same pose-rate cap: below it the poses
  // are not vouched for at all, so a faster scan buys nothing.
  if (t.dwell_floor_ns > 0) dwell = std::max(dwell, std::min(static_cast<double>(t.dwell_floor_ns), rate_cap_dwell));
  return quantize_up(dwell);
}

std::uint32_t ScanSpeedGovernor::next_dwell_ns(std::uint8_t target, std::int32_t w,
                                               std::int32_t h) noexcept {
  TargetState& t = targets_[clamp_target(target)];
  const std::uint32_t want = wanted_dwell_ns(target, w, h);
  if (t.dwell_ns == 0 || want >= t.dwell_ns) {
    t.dwell_ns = want;  // longer: at once (a short scan means an overrun)
    t.decreasing = false;
    return t.dwell_ns;
  }
  if (!t.decreasing && static_cast<double>(want) < t.dwell_ns * (1.0 - config_.hysteresis)) {
    t.decreasing = true;  // left the band: approach the wanted dwell
  }
  if (t.decreasing) {
    const double floor_ns = t.dwell_ns * (1.0 - config_.max_decrease_per_frame);
    t.dwell_ns = std::max(want, quantize_down(std::max(floor_ns, static_cast<double>(want))));
    if (t.dwell_ns <= want) t.decreasing = false;
  }
  return t.dwell_ns;
}

}  // namespace sempose::pipeline
