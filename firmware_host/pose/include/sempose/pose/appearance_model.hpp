// Learned appearance, the non-RT half: from the observer's batches (AppearanceStats), which
// pixels of the pattern the target explains. Per pattern set it keeps the running sums of
// every accepted batch and decides per block_px² block of the pattern's frame: a block whose
// mean squared residual against the recorded pattern exceeds outlier_ratio × what detector
// noise and the pose's jitter explain (noise variance + (jitter² + (angle jitter · r)²) · |∇t|²) is not the target
// (background under the rim that changes as the target moves, a moving jaw) and leaves the
// support. The support stays inside the user's shape mask (a prior) and the pattern circle.
// Drift check (Matthews, Ishikawa & Baker 2004): a new support is kept only if the mean of
// the aligned observations over it still is the recorded pattern — ZNCC >= min_consistency
// at its best integer shift, that shift's sub-pixel peak within max_drift_px of zero — and
// it keeps min_support_fraction of the circle. A rejected batch is not added to the sums, so
// frames tracked at a wrong pose cannot teach the model. Not RT (allocates at construction).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sempose/config/appearance_config.hpp"
#include "sempose/pose/appearance_observer.hpp"

namespace sempose::pose {

struct AppearanceDecision {
  bool accepted = false;
  std::string why;                    // the rejection's reason
  std::vector<std::uint8_t> support;  // size_px², 1 = the target's pixel (when accepted)
  double support_fraction = 0;        // of the circle
  double consistency = 0;             // ZNCC of the mean observation with the recorded pattern
  double drift_px = 0;                // sub-pixel offset of that match
  int frames = 0;                     // frames in the running sums, this batch included
  // Template refinement (cfg.refine_template; only for an accepted batch): the refined template
  // (size_px², prefiltered, the pattern's own frame; empty: no observation has entered yet),
  // the batch's alignment against the recorded pattern (the correction applied to it) and
  // whether it entered the template (template_why: why not).
  std::vector<float> refined;
  double template_noise_factor = 1;   // the refined template's noise variance / the recorded one's (support mean)
  double template_weight = 0;         // the observations' mean weight over the support
  double align_dx = 0, align_dy = 0, align_dphi_deg = 0;
  double motion_px = 0;               // the batch's spread over the background
  bool template_updated = false;
  std::string template_why;
};

class AppearanceModel {
 public:
  // circle: the pattern's support bitmap (size_px²); references[k] / priors[k]: pattern set
  // k's recorded pattern, prefiltered (size_px²), and its shape prior (size_px², 1.0 = may be
  // the target; empty = the whole circle).
  AppearanceModel(const config::AppearanceConfig& cfg, int size_px, const std::uint8_t* circle,
                  std::vector<std::vector<float>> references, std::vector<std::vector<float>> priors);

  // One batch of the observer's: the support it gives with the sums so far, checked.
  AppearanceDecision update(const AppearanceStats& batch);
  // The support the running sums of set k give (no check, no change): for tests and figures.
  std::vector<std::uint8_t> support_of(const AppearanceStats& sums, std::uint8_t set) const;
  // The drift check of a support against set k's recorded pattern (fills consistency, drift_px).
  bool consistent(const AppearanceStats& sums, const std::vector<std::uint8_t>& support, std::uint8_t set,
                  AppearanceDecision& d) const;
  const AppearanceStats& sums(std::uint8_t set) const { return sums_[set]; }
  // Setup: set k's recorded pattern's noise variance per pixel, prefiltered, in the reference's
  // units (the template blend's weight; 0: unknown, the observations are never blended in), and
  // the variance of its central-difference gradient along x or y (what the noise adds to the
  // alignment's JᵀJ: taken out, else the alignment's shift shrinks by H_c / (H_c + N), the
  // errors-in-variables attenuation of fitting against a noisy reference).
  void set_pattern_noise(std::uint8_t set, double var, double grad_var);
  // The warp p = (dx, dy, dφ in degrees) and photometry (gain, offset) with which `obs` (size_px²,
  // pattern units) ≈ gain · t(W(x; p)) + offset over the pixels with valid[i] != 0, t set k's
  // recorded pattern and W(x; p) = c + R(dφ)(x − c) + (dx, dy) (Gauss–Newton, bicubic,
  // weighted by `weight`). False when it did not converge (singular, gain ≤ 0).
  bool align(const std::vector<double>& obs, const std::vector<double>& weight, std::uint8_t set, double p[3],
             double& gain, double& offset) const;

 private:
  config::AppearanceConfig cfg_;
  int n_;
  std::vector<std::uint8_t> circle_;
  std::int64_t circle_count_ = 0;
  std::vector<std::vector<float>> refs_;
  std::vector<std::vector<float>> grad2_;  // |∇t|² of each reference
  std::vector<std::vector<float>> priors_;  // 1.0 = may be the target; empty = the circle
  std::vector<AppearanceStats> sums_;
  // Template refinement: per set, the recorded pattern's noise variance, and the running sums
  // of the drift-corrected observations (Σ hits·o, Σ hits) and of their per-frame noise.
  void refine_template(const AppearanceStats& batch, const std::vector<std::uint8_t>& support, AppearanceDecision& d);
  std::vector<double> pattern_var_, grad_var_;
  std::vector<std::vector<double>> tsum_, thits_;
  std::vector<double> tnoise_;
  std::vector<int> tframes_;
};

}  // namespace sempose::pose
