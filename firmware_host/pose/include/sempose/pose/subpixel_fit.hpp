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

  // gaussian: fit log scores (falls back to scores); noise_correction: see fit_at.
  SubpixelFit(bool gaussian, bool noise_correction) noexcept;

  bool gaussian() const noexcept { return gaussian_; }

  // The joint fit around (ux, uy, j) on the cache's exact scores. The window variance of a
  // noisy frame is signal plus noise, and ZNCC = Σtf/√(signal+noise) leans towards
  // displacements whose window holds more signal variance (and, for shot noise, more noise) —
  // a bias that turns with the target. With noise_correction the fit therefore uses
  // Σtf/√(var − noise var), the noise variance taken from the best match itself (var₀ − (Σtf)₀²:
  // what the pattern does not explain there). False when a sample leaves the ROI or the
  // surface has no clear maximum within 1.5 steps.
  bool fit_at(ScoreCache& cache, int ux, int uy, int j, double& dx, double& dy, double& dj) const noexcept;

  // Peak of the quadratic fitted to 19 samples (kOffsets order): solves H·u = −g. False when
  // the surface is not a clear maximum (H not negative definite) or the peak lies more than
  // 1.5 steps out.
  bool joint_fit(const float* samples, bool log_scores, double& dx, double& dy, double& dj, float& peak) const noexcept;

 private:
  static void terms(double x, double y, double j, double* t) noexcept;
  bool gaussian_, noise_correction_;
  double pinv_[kTerms][kSamples] = {};  // (AᵀA)⁻¹Aᵀ of the fixed design
};

}  // namespace sempose::pose
