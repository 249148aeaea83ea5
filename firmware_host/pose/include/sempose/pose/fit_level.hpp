#pragma once
// The target's own level of fit quality: how much of its window the pattern leaves unexplained
// on frames it tracked well, as the normalised χ² (1 − s²)/(1 − a²) (the residual over what the
// noise model predicts; 1 for a perfect model). A pose whose χ² lies far above that level is a
// pose the model does not fit the way it fits this target: a look-alike, the target half under
// an occluder, a hypothesis turned 90° that a re-acquisition search took. The level is kept in
// the log (a ratio is what changes with dose and content) over the last kCapacity well-tracked
// frames, robustly: median and MAD, so a few odd frames among them move neither.
//
// RT: a fixed ring, no allocation; nth_element over ≤ kCapacity values.
#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

namespace sempose::pose {

class FitLevel {
 public:
  static constexpr int kCapacity = 32;
  // Fewer frames than this say nothing about the target's spread: no judgement yet.
  static constexpr int kMinFrames = 8;

  void forget() noexcept { count_ = next_ = 0; }
  bool known() const noexcept { return count_ >= kMinFrames; }

  // A well-tracked frame's χ² (> 0) joins the level.
  void learn(double chi2) noexcept {
    if (!(chi2 > 0) || !std::isfinite(chi2)) return;
    ring_[next_] = static_cast<float>(std::log(chi2));
    next_ = (next_ + 1) % kCapacity;
    count_ = std::min(count_ + 1, kCapacity);
  }

  // The level: the median χ² of those frames (known() first).
  double chi2() const noexcept { return std::exp(median_and_sd().first); }

  // χ² significantly above the level: its log beyond the median by z SDs of one frame's log χ²
  // about the median — the larger of the frames' own robust spread (1.4826 × MAD) and
  // floor_sd, the detector noise's share alone — widened for the median's own error
  // (variance π/2 · sd²/n).
  bool significantly_above(double chi2, double z, double floor_sd) const noexcept {
    return excess_sds(chi2, floor_sd) > z;
  }
  // How many of those SDs the value's log lies above the level's (−∞: not known, or no value).
  double excess_sds(double value, double floor_sd) const noexcept {
    if (!known() || !(value > 0) || !std::isfinite(value)) return -HUGE_VAL;
    const double sd = spread(floor_sd);
    return sd > 0 ? excess(value) / sd : (excess(value) > 0 ? HUGE_VAL : -HUGE_VAL);
  }

  // log value over the level's (known() first), and the SD one frame's log has about it (the
  // larger of the robust spread and floor_sd, widened for the median's own error).
  double excess(double value) const noexcept { return std::log(value) - median_and_sd().first; }
  double spread(double floor_sd) const noexcept {
    return std::max(median_and_sd().second, floor_sd) * std::sqrt(1.0 + 1.5708 / std::max(1, count_));
  }

 private:
  // Median of the logs and 1.4826 × their median absolute deviation (the SD for a normal).
  std::pair<double, double> median_and_sd() const noexcept {
    std::array<float, kCapacity> v{};
    std::copy(ring_.begin(), ring_.begin() + count_, v.begin());
    const int mid = count_ / 2;
    std::nth_element(v.begin(), v.begin() + mid, v.begin() + count_);
    const double median = v[mid];
    for (int i = 0; i < count_; ++i) v[i] = std::fabs(v[i] - static_cast<float>(median));
    std::nth_element(v.begin(), v.begin() + mid, v.begin() + count_);
    return {median, 1.4826 * v[mid]};
  }

  std::array<float, kCapacity> ring_{};
  int count_ = 0;
  int next_ = 0;
};

}  // namespace sempose::pose
