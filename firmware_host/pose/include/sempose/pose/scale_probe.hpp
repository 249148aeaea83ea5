// The scale estimate of one frame (issue 13 item 2): at the walk's pose, the ZNCC of the bank's
// pattern stretched by 1 − δ, 1 and 1 + δ about its centre (bilinear) against the loaded ROI's
// own pixels (every third row and column of the support stretched by 1 − δ, the same pixels
// for the three); a parabola
// through the three gives the residual scale of the ROI as loaded (the tracker folds it into
// its running scale, which resamples the next ROI). Reads the exact scorer's loaded ROI. RT,
// no allocation.
#pragma once

#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/measurement.hpp"
#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {

struct ScaleReading {
  bool valid = false;   // false: the window left the ROI or the scores have no maximum
  double factor = 1.0;  // the target's size in the loaded ROI over the pattern's
};

class ScaleProbe {
 public:
  static constexpr double kStep = 0.03;
  static constexpr int kStride = 3;  // rows and columns of the ROI read  // δ: about the width of the score's peak in scale at ~100 px

  explicit ScaleProbe(const ExactScorer& scorer) noexcept : scorer_(scorer) {}

  ScaleReading read(const PatternBank& bank, const Measurement& m) const noexcept;
  // The ZNCC at the pose of m with the pattern grid stretched by `factor`, over the ROI pixels
  // of the pattern's support stretched by `window` (≤ factor; the same for the scores compared)
  // (-2 outside the ROI).
  // stride: rows and columns of the ROI read (1: every pixel, for comparing candidates).
  double score(const PatternBank& bank, const Measurement& m, double factor, double window,
               int stride = kStride) const noexcept;

 private:
  const ExactScorer& scorer_;
};

}  // namespace sempose::pose
