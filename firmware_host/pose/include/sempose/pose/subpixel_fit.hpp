// Sub-pixel / sub-step fit of the score peak. The joint fit: a quadratic in (dx, dy, dj) — 10
// coefficients, cross terms included — least-squares over 19 exact scores around the integer
// maximum: the 3×3 position neighbourhood at angle j and the 5-point crosses at j±1. Separate
// 3-point fits per axis are biased whenever the peak is tilted (an edge at an angle couples x
// and y; content off the pattern centre couples position and angle) by up to a few tenths of
// a pixel/degree; they remain the fallback where the joint fit finds no clear maximum.
// Construction (the design's pseudo-inverse) is setup; the fits are RT.
#pragma once

#include "sempose/pose/score_cache.hpp"

namespace sempose::pose {

// Offset of a peak from three samples (left, centre, right), in [-0.5, 0.5]; on log scores
// (a Gaussian peak) when gaussian and all three are positive.
double fit3(float left, float centre, float right, bool gaussian) noexcept;

class SubpixelFit {
 public:
  static constexpr int kSamples = 19, kTerms = 10;
  // (dx, dy, dj) of the 19 samples.
  static constexpr int kOffsets[kSamples][3] = {
      {-1, -1, 0}, {0, -1, 0}, {1, -1, 0}, {-1, 0, 0}, {0, 0, 0}, {1, 0, 0}, {-1, 1, 0}, {0, 1, 0}, {1, 1, 0},
      {0, 0, -1},  {-1, 0, -1}, {1, 0, -1}, {0, -1, -1}, {0, 1, -1},
      {0, 0, 1},   {-1, 0, 1},  {1, 0, 1},  {0, -1, 1},  {0, 1, 1}};

  // gaussian: fit log scores (falls back to scores); noise_correction, background_plane: see fit_at.
  SubpixelFit(bool gaussian, bool noise_correction, bool background_plane = false) noexcept;
  // The plane's significance (below): its Σ² over the residual variance per support pixel.
  // Counted per pixel, though the prefilter correlates neighbours: 100 keeps the plane off where
  // the pose's noise outweighs the bias it takes away (measured, pose_accuracy_bench --quick, the
  // position error against the plane-free fit's at 2.5 / 20 e-/px: threshold 30 1.04 / 0.96, 100
  // 1.00 / 0.96, 300 1.00 / 0.95, always 1.03 / 0.96).
  static constexpr double kPlaneSignificance = 100.0;

  bool gaussian() const noexcept { return gaussian_; }

  // The joint fit around (ux, uy, j) on the cache's exact scores. The window variance of a
  // noisy frame is signal plus noise, and ZNCC = Σtf/√(signal+noise) leans towards
  // displacements whose window holds more signal variance (and, for shot noise, more noise) —
  // a bias that turns with the target. With noise_correction the fit therefore uses
  // Σtf/√(var − noise var), the noise variance taken from the best match itself (var₀ − (Σtf)₀²:
  // what the pattern does not explain there). False when a sample leaves the ROI or the
  // surface has no clear maximum within 1.5 steps.
  //
  // With background_plane, where a brightness ramp across the window (charging: the
  // background's gain or level rising from one side to the other; a target's surroundings
  // brighter on one side than in the recording) explains significantly more than noise would
  // (kPlaneSignificance), every sample is scored as √(Σ² explained by pattern and plane) / √(var
  // − noise var), the noise variance now what pattern and plane leave: the peak of the likelihood
  // with gain, offset and the plane's two slopes free. A ZNCC over a ramp pulls the peak towards
  // the ramp's bright side (measured: a ×4 gain ramp across the ROI, 0.8–1.7 px in x).
  // plane_used (when given): whether the samples were scored with the background plane.
  bool fit_at(ScoreCache& cache, int ux, int uy, int j, double& dx, double& dy, double& dj,
              bool* plane_used = nullptr) const noexcept;

  // Peak of the quadratic fitted to 19 samples (kOffsets order): solves H·u = −g. False when
  // the surface is not a clear maximum (H not negative definite) or the peak lies more than
  // 1.5 steps out.
  bool joint_fit(const float* samples, bool log_scores, double& dx, double& dy, double& dj, float& peak) const noexcept;

 private:
  static void terms(double x, double y, double j, double* t) noexcept;
  // The 19 samples scored with the background plane (fit_at), in fs; false (fs untouched) when
  // the plane is not significant at the centre or a sample leaves the ROI.
  bool plane_scores(ScoreCache& cache, int ux, int uy, const CachedScore* ev, float* fs) const noexcept;

  bool gaussian_, noise_correction_, background_plane_;
  double pinv_[kTerms][kSamples] = {};  // (AᵀA)⁻¹Aᵀ of the fixed design
};

}  // namespace sempose::pose
