// The one exact scorer of the pose engine: the ZNCC of one bank angle at one integer
// displacement of the loaded ROI, at full resolution, over that angle's support. The window's
// mean and variance come from the ROI's summed-area tables (four look-ups per support band;
// tabled on demand over the windows scored, so the tables are mutable state of a const score),
// Σ t·f from one dot product (the pattern is zero-mean and unit norm under its support). The
// orientation walk, the fit and the start search all score through this class; its unit test
// checks it against a brute-force ZNCC.
// Construction is setup; load() and the scores are RT.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "sempose/pose/pattern_bank.hpp"
#include "sempose/pose/pattern_support.hpp"
#include "sempose/pose/summed_area_table.hpp"

namespace sempose::pose {

// The parts of one exact score: tf = Σ t·f, var = Σ f² − (Σ f)²/n over the support, n.
struct ScoreParts {
  bool inside = false;  // false: the window leaves the ROI (no score)
  double tf = 0, var = 0, count = 0;
  double sum = 0;  // Σ f over the support (filtered units, before the ROI's mean is taken off)
};

// The background plane's products with one window (PatternBank::PlaneGram): Σ (x − mean_x)·f
// and Σ (y − mean_y)·f over the support, x and y in pattern widths from its centre.
struct PlaneParts {
  bool inside = false;
  double xf = 0, yf = 0;
};

class ExactScorer {
 public:
  // fine_mask: the full-resolution circle (the dot product runs over it, widened to vector
  // chunks); max_roi_px: the largest ROI side loaded.
  ExactScorer(const PatternMask& fine_mask, int max_roi_px);

  // RT: keeps the prefiltered ROI (w×h, row stride w) minus its mean, and tables it on demand:
  // `filtered` must stay as it is until the next load (the loader's own buffer).
  void load(const std::int32_t* filtered, int w, int h) noexcept;
  int max_roi_px() const noexcept { return max_roi_px_; }
  int roi_w() const noexcept { return roi_w_; }
  int roi_h() const noexcept { return roi_h_; }
  // The loaded ROI, prefiltered, minus its mean (roi_w() × roi_h(), row stride roi_w()): what
  // the scale probe and the appearance observer sample.
  const float* roi() const noexcept { return roi_.data(); }

  // RT: the parts at angle j of the bank, pattern top-left at (ux, uy) of the ROI.
  ScoreParts parts(const PatternBank& bank, int j, int ux, int uy) const noexcept;
  // ZNCC from the parts; a flat window (std under half a filtered unit) scores 0.
  static float zncc(const ScoreParts& p) noexcept;
  // RT: the plane's products for the window whose parts() are p (a pass over the support).
  PlaneParts plane_parts(const PatternBank& bank, int j, int ux, int uy, const ScoreParts& p) const noexcept;
  // RT: the same for a window whose support sums to sum_f in roi() (the mean-free ROI).
  PlaneParts plane_parts_given_sum(const PatternBank& bank, int j, int ux, int uy, double sum_f) const noexcept;
  // RT: the plane's products at the 3×3 places around (ux, uy) — out[(ox + 1) + 3·(oy + 1)] —
  // for angle j's support, three passes over it (one per row offset; the column offsets from
  // each row's sums and its two end pixels). All nine not inside when one place leaves the ROI.
  void plane_parts_3x3(const PatternBank& bank, int j, int ux, int uy, PlaneParts* out) const noexcept;
  // RT: the score itself, -2 outside the ROI.
  float score(const PatternBank& bank, int j, int ux, int uy) const noexcept;

  std::size_t memory_bytes() const noexcept;

 private:
  int pattern_px_;
  int max_roi_px_ = 0;
  std::vector<MaskBand> chunk_bands_;  // the circle widened to 16-float chunks
  int roi_w_ = 0, roi_h_ = 0;
  double roi_mean_ = 0;                // what load() took off the filtered ROI
  std::vector<float> roi_;             // prefiltered ROI minus its mean (row stride roi_w_)
  mutable SummedAreaTables tables_;     // on demand (cover() in parts())
};

}  // namespace sempose::pose
