// The final fit of a tracked pose: Gauss–Newton in the inverse-compositional form (Baker &
// Matthews) of a pattern template against the loaded ROI — position, angle, optionally scale (a
// similarity warp about the pattern's centre) with a photometric gain and offset:
//   min Σ_d (f(c + s·R(φ)·d) − a·T(d) − b)²,  R(φ) = [[cos, sin], [−sin, cos]]
// over the template's support pixels whose four neighbours are in it too (T's gradient is a
// central difference there). f is sampled bilinearly. Two sources (tracker.refine.source):
// the prefiltered ROI against the bank's prefiltered angle-0 copy over its support (the exact
// scorer's pixels and objective), or the raw ROI against the recorded pattern, optionally
// low-passed on its own side (tracker.refine.template_passes). With noise weights
// (tracker.refine.noise_weights) the sum is Σ_d w(d)·(…)², w = 1 / the detector's variance at
// the template's signal: fixed per template, so the weighted Hessian is still the template's.
//
// FitTemplate::build is setup (allocates; one per pattern set): in the inverse-compositional
// form the steepest-descent images and the Hessian are the template's alone. fit() is RT:
// noexcept, allocation-free, at most max_iterations passes over the support. A cost increase
// ends the iterations at the pose before it; a step or a total move beyond max_move_px (the
// rim's displacement for angle and scale) keeps the start (diverged).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "sempose/config/refine_config.hpp"

namespace sempose::pose {

enum class FitStatus : std::uint8_t {
  kOff = 0,       // not run (tracker.refine.enabled false)
  kRefined = 1,   // the pose is the fit's
  kDiverged = 2,  // a step left the basin or the system was singular: the start pose is kept
  kSkipped = 3,   // not run: score below min_score, the pose's pixels leave the ROI, a flat window
};

// The template's centre pixel ((P−1)/2, (P−1)/2) at (cx, cy) (ROI px), turned phi_deg
// (counter-clockwise on screen, README: Conventions), scaled by scale.
struct FitPose {
  double cx = 0, cy = 0, phi_deg = 0, scale = 1;
};

struct FitResult {
  FitStatus status = FitStatus::kOff;
  FitPose pose;             // the fit's pose; the start when not kRefined
  int iterations = 0;       // passes over the pixels
  double gain = 0, offset = 0;
  double rms_residual = 0;  // √(Σ r²/n) at the returned pose
};

inline constexpr int kFitParams = 6;  // tx, ty, θ, ln s (the template's frame), gain, offset

// One template (setup): its inner support pixels, values, steepest-descent images and moments.
class FitTemplate {
 public:
  // img: P×P floats; inside: P×P, non-zero = support. variance: P×P relative noise variance
  // per pixel (> 0; the weights are its inverse, normalised to mean 1 over the inner pixels),
  // or null for equal weights. False when under 64 inner pixels.
  bool build(const float* img, int size_px, const std::uint8_t* inside, const float* variance = nullptr);
  int pixels() const noexcept { return n_; }
  double radius_px() const noexcept { return radius_; }
  std::size_t memory_bytes() const noexcept { return 8 * t_.size() * sizeof(float); }

 private:
  friend class GaussNewtonFit;
  int n_ = 0;
  double radius_ = 0;
  // Per inner pixel: offsets (u, v), the weight w and w·T, w·sd0..w·sd3 (the steepest-descent
  // images times the weight; w = 1 without weights, so these are then T and sd exactly).
  std::vector<float> u_, v_, w_, t_, sd0_, sd1_, sd2_, sd3_;
  double m_[kFitParams][kFitParams] = {};  // Σ w J Jᵀ, J = (sd0..sd3, T, 1)
  // w_i·σ_i² over σ̄² (σ_i² ∝ the variance the weights were built from, σ̄² its mean): 1 unweighted.
  double noise_factor_ = 1.0;
};

class GaussNewtonFit {
 public:
  explicit GaussNewtonFit(const config::RefineConfig& cfg) : cfg_(cfg) {}

  // roi: w×h pixels, row stride `stride`; start: the walk's pose.
  FitResult fit(const FitTemplate& tpl, const float* roi, int w, int h, std::ptrdiff_t stride,
                const FitPose& start) const noexcept;
  FitResult fit(const FitTemplate& tpl, const std::uint16_t* roi, int w, int h, std::ptrdiff_t stride,
                const FitPose& start) const noexcept;

  const config::RefineConfig& config() const noexcept { return cfg_; }

 private:
  template <class Px>
  FitResult run(const FitTemplate& tpl, const Px* roi, int w, int h, std::ptrdiff_t stride,
                const FitPose& start) const noexcept;

  config::RefineConfig cfg_;
};

}  // namespace sempose::pose
