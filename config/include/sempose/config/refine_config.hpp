// Settings of the final Gauss–Newton fit at the refinement seam (the `tracker.refine:` mapping;
// firmware_host/pose gauss_newton_fit / pose_refinement). After the orientation walk's
// quadratic fit, the fit moves the pose (x, y, φ and optionally scale, with gain and offset)
// to the least-squares match of the bank's pattern at the walk's angle on the prefiltered ROI.
#pragma once

#include <cstdint>
#include <string>

namespace sempose::config {

class Section;

struct RefineConfig {
  bool enabled = false;
  // Gauss–Newton passes over the pattern's pixels per frame (the worst case: this many).
  std::int32_t max_iterations = 3;
  // A fit that moves the pose farther than this from the walk's (rim displacement for angle
  // and scale, in px) left the walk's basin: the walk's pose is kept and marked.
  double max_move_px = 1.5;
  // What is fitted: "prefiltered" — the exact scorer's prefiltered ROI against the bank's
  // prefiltered pattern over its support (the walk's own objective); "raw" — the ROI as scanned
  // against the recorded pattern over the same support (no prefilter: the least-squares
  // estimator for white noise, but the recorded background under the rim pulls it harder).
  std::string source = "prefiltered";
  // Fit the scale too (otherwise the ROI's tracked scale is taken as exact).
  bool fit_scale = true;
  // Report the fit's position (false: only its angle, the walk's position kept — the fit
  // still moves position jointly to find the angle). Measured: the fit lowers the angle's
  // noise part but not the position's (README: Known limitations).
  bool fit_position = true;
  // Report the fit's angle (and scale); false: the walk's angle kept (the fit still moves the
  // angle jointly to find the position).
  bool fit_angle = true;
  // Only measurements scoring at least this are refined (below it the fit has too little signal
  // to beat the walk and a look-alike is as likely).
  double min_score = 0.2;
  // Raw source: 5-tap binomial low-pass passes (σ ≈ 1 px each) applied to the recorded pattern
  // only — the template side of the fit — so the recorded pattern's own noise does not enter
  // the fit unfiltered while the frame is fitted as scanned. 0: the recorded pattern as is.
  // −1 (auto): the passes (0..3) that minimise the fit's predicted position variance given the
  // pattern's noise measured at setup (PoseRefinement::auto_template_passes). Ignored with the
  // prefiltered source (its template is the bank's prefiltered copy).
  std::int32_t template_passes = 0;
  // Weight each pixel's residual by 1 / its detector variance (Poisson + gain cascade + read
  // noise: variance ∝ signal above the black level + read noise), the signal taken from the
  // recorded pattern smoothed by two binomial passes (fixed per pattern set at setup, so the
  // weighted Hessian is precomputed). Needs the recorded pattern (both sources).
  bool noise_weights = false;
  // The detector's output at zero signal, as a fraction of full scale (2^bits − 1): the
  // simulator's output_offset (0.04). Only read with noise_weights.
  double black_level = 0.04;
  // The read noise's share of the variance, in counts of signal (the signal above the black
  // level at which the shot noise equals it: read_noise² / (counts per electron × excess
  // noise)), added to every pixel's; each pixel's signal is taken as at least 2 % of the
  // pattern's mean over its support, so no weight is unbounded. Only read with noise_weights.
  double read_noise_counts = 0.0;
};

// Reads a `refine:` mapping (tracker.refine); config/src/refine_section.cpp.
void read_refine(Section& section, RefineConfig& out);

}  // namespace sempose::config
