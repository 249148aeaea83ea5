// The seam for a model-based refinement of a tracked measurement, right after the orientation
// walk and the sub-pixel fit (and the recovery sweep), before the loss policy judges it.
// Today it passes the measurement through unchanged; a refinement (e.g. Gauss–Newton on the
// exact scores, scale) replaces refine()'s body. It sees the ROI the measurement was made in
// (the scorer holds it) and the bank. The start search's result is not passed through here:
// the scorer then holds the last candidate's ROI, not necessarily the winner's, and the next
// frame (tracked at the found pose) is refined anyway. RT: noexcept, no allocation.
#pragma once

#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/measurement.hpp"

namespace sempose::pose {

class PoseRefinement {
 public:
  PoseRefinement(const ExactScorer& scorer) noexcept : scorer_(scorer) {}

  Measurement refine(const PatternBank& bank, const Measurement& m) const noexcept {
    (void)bank;
    (void)scorer_;
    return m;
  }

 private:
  const ExactScorer& scorer_;
};

}  // namespace sempose::pose
