// From a position peak of the binned map to one measurement on exact full-resolution scores:
// the position hill-climb at the start angle, the paper's orientation walk (j, j±1, move to
// the better neighbour until the centre wins, at most max_moves steps), the climb again if
// the angle moved, then the sub-pixel / sub-step fit. RT, no allocation.
#pragma once

#include "sempose/pose/angle_grid.hpp"
#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/measurement.hpp"
#include "sempose/pose/peak_finder.hpp"
#include "sempose/pose/subpixel_fit.hpp"

namespace sempose::pose {

class OrientationWalk {
 public:
  OrientationWalk(const ExactScorer& scorer, const SubpixelFit& fit, const AngleGrid& angles) noexcept
      : scorer_(scorer), fit_(fit), angles_(angles) {}

  // half_peak: the peak in the 2×2-binned map of the ROI the scorer holds, at angle j.
  Measurement measure(const PatternBank& bank, int j, const Peak& half_peak, int max_moves) const noexcept;

 private:
  const ExactScorer& scorer_;
  const SubpixelFit& fit_;
  const AngleGrid& angles_;
};

}  // namespace sempose::pose
