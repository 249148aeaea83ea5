// The refinement seam: right after the orientation walk and its sub-pixel fit (and the recovery
// sweep), before the motion check and the loss policy judge the measurement. With
// tracker.refine.enabled it replaces the walk's sub-pixel / sub-step offsets by the final
// Gauss–Newton fit of the pattern (gauss_newton_fit.hpp), started at the walk's pose; otherwise,
// and when the fit is skipped or diverges, the walk's measurement passes unchanged (marked in
// Measurement::refine_status). The grid point (j, ux, uy) and the exact score stay the walk's:
// the scale probe, σ and the loss policy read them. The start search's result is not passed
// through here: the scorer then holds the last candidate's ROI, not necessarily the winner's,
// and the next frame (tracked at the found pose) is refined anyway.
// Setup: add_set() per pattern set (allocates the templates). refine() is RT: noexcept, no
// allocation.
#pragma once

#include <cstdint>
#include <vector>

#include "sempose/config/refine_config.hpp"
#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/gauss_newton_fit.hpp"
#include "sempose/pose/measurement.hpp"
#include "sempose/pose/pattern_bank.hpp"
#include "sempose/pose/pattern_image.hpp"

namespace sempose::pose {

// The raw ROI the exact scorer's copy was loaded from (the rescaled one when resampled).
struct RawRoi {
  const std::uint16_t* px = nullptr;
  std::ptrdiff_t stride = 0;
};

class PoseRefinement {
 public:
  PoseRefinement(const ExactScorer& scorer, const config::RefineConfig& cfg, double angle_step_deg)
      : scorer_(scorer), fit_(cfg), step_deg_(angle_step_deg), raw_(cfg.source == "raw") {}

  // Setup, per pattern set in order: the template over the bank's angle-0 support — the bank's
  // prefiltered copy, or the recorded pattern (raw source) after template_passes binomial
  // passes; with noise_weights the weights from the recorded pattern (levels of `bits` bits,
  // black_level a fraction of that full scale). False when it has too few pixels.
  bool add_set(const PatternBank& bank, const PatternImage& recorded, int bits = 8);

  Measurement refine(std::uint8_t set, const PatternBank& bank, const Measurement& m, const RawRoi& raw) const noexcept;

  std::size_t memory_bytes() const noexcept;

  // The template's low-pass passes of pattern set `set` (template_passes, or what auto chose).
  int template_passes(std::size_t set) const noexcept { return set < passes_.size() ? passes_[set] : 0; }

  // template_passes auto (setup): the passes, 0..kMaxAutoPasses, that minimise the predicted
  // variance of the fit's position given the recorded pattern's own noise (pose_refinement.cpp).
  static constexpr int kMaxAutoPasses = 3;
  static int auto_template_passes(const PatternImage& recorded, const std::vector<std::uint8_t>& inside);

 private:
  const ExactScorer& scorer_;
  GaussNewtonFit fit_;
  double step_deg_;
  bool raw_;
  std::vector<FitTemplate> templates_;
  std::vector<int> passes_;
};

}  // namespace sempose::pose
