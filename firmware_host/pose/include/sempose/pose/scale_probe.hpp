// The scale estimate of one frame (issue 13 item 2): at the walk's pose, the ZNCC of the bank's
// pattern stretched by 1 − δ, 1 and 1 + δ about its centre (bilinear) against the loaded ROI's
// own pixels (every third row and column of the support stretched by 1 − δ, the same pixels
// for the three); a parabola
// through the three gives the residual scale of the ROI as loaded (the tracker folds it into
// its running scale, which resamples the next ROI). Reads the exact scorer's loaded ROI. RT,
// no allocation.
#pragma once

#include <vector>

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

  // Setup (allocates the per-column scratch for the largest ROI the scorer loads).
  explicit ScaleProbe(const ExactScorer& scorer)
      : scorer_(scorer),
        columns_(static_cast<std::size_t>(scorer.max_roi_px())),
        columns3_(static_cast<std::size_t>(scorer.max_roi_px())) {}

  ScaleReading read(const PatternBank& bank, const Measurement& m) const noexcept;
  // The ZNCC at the pose of m with the pattern grid stretched by `factor`, over the ROI pixels
  // of the pattern's support stretched by `window` (≤ factor; the same for the scores compared)
  // (-2 outside the ROI).
  // stride: rows and columns of the ROI read (1: every pixel, for comparing candidates).
  double score(const PatternBank& bank, const Measurement& m, double factor, double window,
               int stride = kStride) const noexcept;

 private:
  // What a column of the window reads of the stretched pattern: the same for every row, so
  // worked out once per score instead of once per pixel (the start search's refinement spent
  // most of its time on these per-pixel products and roundings).
  struct Column {
    int u0 = 0;       // left neighbour in the pattern (bilinear)
    int u_near = 0;   // nearest pattern column of the support stretched by `window`
    double wu = 0;    // weight of the right neighbour
  };
  struct Column3 {
    int u0[3] = {};
    int u_near = 0;
    double wu[3] = {};
  };
  // The three stretches over one window in one pass over its pixels: each score's sums are
  // the same sequence of adds as score()'s (the same values to the bit), the window's own
  // (Σf, Σf², n) taken once, and the three scores' independent sums interleaved.
  void score3(const PatternBank& bank, const Measurement& m, const double factor[3], double window, int stride,
              double out[3]) const noexcept;

  const ExactScorer& scorer_;
  mutable std::vector<Column> columns_;  // scratch, one per ROI column read (RT: no allocation)
  mutable std::vector<Column3> columns3_;  // the same for score3  // scratch, one per ROI column read (RT: no allocation)
};

}  // namespace sempose::pose
