// The scale levels the start search covers around the expected scale (as factors of it): 1,
// then geometric steps of kSearchLevelRatio below and above it until the levels, each good for
// ±√ratio, reach tracker.search_scale_min and search_scale_max (0.75–1.33: 0.8, 1, 1.25).
// Setup only (allocates).
#pragma once

#include <cmath>
#include <vector>

#include "sempose/config/tracker_config.hpp"

namespace sempose::pose {

// Levels this far apart leave a candidate at most √1.25 ≈ 11.8 % off the target's size: the
// ×8 coarse pattern (16 px) still peaks there (its rim moves by < 1 coarse px) and the scale
// refinement's span covers it. Closer levels cost a coarse pass each (18 FFTs at the size the
// smallest level enlarges the frame to): 5 levels at 1.16 took 2.5× the scale-1 search.
inline constexpr double kSearchLevelRatio = 1.25;
// The scales the tracker can follow (its ROI must hold the target): levels are kept inside.
inline constexpr double kTrackedScaleMin = 0.7, kTrackedScaleMax = 1.45;

inline std::vector<double> search_scale_levels(const config::TrackerConfig& c) {
  const double half = 0.5 * std::log(kSearchLevelRatio);
  auto count = [&](double span) { return span > 0 ? static_cast<int>(std::ceil((span - half) / std::log(kSearchLevelRatio) - 1e-9)) : 0; };
  const int below = std::max(0, count(std::log(1.0 / c.search_scale_min)));
  const int above = std::max(0, count(std::log(c.search_scale_max)));
  std::vector<double> v{1.0};
  for (int i = 1; i <= below; ++i) v.push_back(std::pow(kSearchLevelRatio, -i));
  for (int i = 1; i <= above; ++i) v.push_back(std::pow(kSearchLevelRatio, i));
  return v;
}

}  // namespace sempose::pose
