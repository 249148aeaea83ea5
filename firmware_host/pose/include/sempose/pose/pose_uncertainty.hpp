// σ of one tracked pose (issue 13 item 5): a cluster-robust ("sandwich") covariance of the
// pose's least-squares fit, computed on the loaded ROI at the walk's pose.
//
// Model: ROI(pattern origin + q) = gain · T_j(q warped by (x, y, φ, scale)) + offset + residual.
// With J the residual's Jacobian w.r.t. (x, y, φ, scale, gain, offset) at the pose (∂T/∂x, ∂y by
// central differences of the bank copy, ∂/∂φ from the neighbouring bank angles, ∂/∂scale the
// radial derivative), H = JᵀJ and g_b = J_bᵀ r_b summed over square tiles b of the pattern:
//     Cov = H⁻¹ (Σ_b g_b g_bᵀ) H⁻¹ .
// Why not Fisher × χ²: the error is dominated by a spatially correlated model error (the
// background under the pattern's rim differs wherever the target moves; the prefilter and the
// PSF correlate the noise too), which Fisher information, assuming independent pixels, misses by
// 2–5×. The tile sums keep whatever is correlated within a tile, so σ grows exactly when the
// residual is structured. The residual is taken at the walk's sub-pixel / sub-step pose (its
// offsets from the integer grid point are applied to first order); the walk's distance from the
// least-squares optimum, δ = H⁻¹ Σ_b g_b, is added as δδᵀ (the walk's own fit error), and the
// white-noise part s²·H⁻¹ with its own factor.
// The recorded pattern's own noise (PatternBank::noise_gram, measured at setup): its gradients
// are in J too, so JᵀJ = H_c + N holds the noise's gradient energy N, while the fit's curvature
// is H_c (the noise's share of JᵀJ is cancelled by the Σ r·∂²T term: E[Σ n ∂²n] = −N) — H⁻¹ is
// too small by (1 + N/H_c) and the spread of Jᵀr the sandwich measures already holds both
// noises (the residual holds the frame's and the pattern's noise, J the noise's gradients: the
// noise × noise term). So the stage's bread is H_c⁻¹ = (JᵀJ − N)⁻¹ and the white-noise part
// s²·H_c⁻¹ (H_c + N) H_c⁻¹: σ rises with a noisy pattern (low dose) and stays for a clean one. The factors (set at setup) were fitted on part
// of the benchmark's targets; README: Uncertainty says how and what they give on the others.
// The frame's sharpness against the pattern (PoseSigma::sharpness): the bread above is the
// pattern copy's own curvature, JᵀJ, which is the fit's curvature only when the frame looks like
// the pattern. A frame blurrier than the pattern (defocus) flattens the fit: its curvature is
// the cross term Σ ∂T·∂f / gain (the copy's gradients against the frame's), smaller than Σ (∂T)²
// by the blur, and the pose's error grows by the same factor (README: Uncertainty, *Sharpness*).
// The stage measures that ratio; the tracker compares it with the target's own (sharpness_level.hpp).
// RT: noexcept, no allocation (buffers and the per-angle JᵀJ cache are sized at setup), one
// pass over the support (and one more for the sharpness).
#pragma once

#include <cstdint>
#include <vector>

#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/measurement.hpp"
#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {

// In the loaded ROI's pixels (the tracker converts a resampled ROI back to the scanned one).
struct PoseSigma {
  bool valid = false;  // false: the window left the ROI, the fit is singular or the ROI flat
  double x_px = 0, y_px = 0, phi_deg = 0, scale = 0;
  // Σ ∂T·∂f / (gain · Σ (∂T)²) over x and y, at the support's inner pixels (all four neighbours in
  // it): 1 for a frame that is the copy times a gain plus noise, lower for a blurrier frame (a
  // constant below 1 for a pattern whose copy holds noise or detail the target's frames do not:
  // only its ratio to the target's own level means something). 0: not measured.
  double sharpness = 0;
  // The detector noise's SD of that ratio (white-noise approximation, the residual's variance).
  double sharpness_sd = 0;
};

class PoseUncertainty {
 public:
  static constexpr int kDefaultTilePx = 8;
  // Setup: pattern_px the bank's pattern side; tile_px the side of a tile (≥ 1); calibration
  // the factor on the sandwich and step part (1: as it is); floor_px, floor_deg the model-error
  // floor added in quadrature to σx, σy and σφ (0: none); noise_factor the factor on the
  // white-noise (Fisher × residual variance) part added in quadrature (0: none); angle_factor
  // a further factor on σφ's two parts (the walk's angle fit is less efficient than its position);
  // scale_factor the same on σscale (the scale probe's reading is not the fit's optimum either).
  // max_angles: the banks' angle count, for the per-angle cache of JᵀJ (0: no cache).
  // pattern_noise: take the recorded pattern's noise (the bank's noise_gram) out of JᵀJ.
  PoseUncertainty(const ExactScorer& scorer, int pattern_px, int tile_px, double calibration, double floor_px = 0,
                  double floor_deg = 0, double noise_factor = 0, double angle_factor = 1, int max_angles = 0,
                  bool pattern_noise = true, double scale_factor = 1);

  // At most this share of a diagonal of JᵀJ is taken as the pattern's noise (a pattern that is
  // mostly noise would otherwise leave a singular H_c).
  static constexpr double kMaxNoiseShare = 0.8;

  // RT: σ of the measurement m of the loaded ROI against bank angle m.j; scale_factor is the
  // scale probe's reading of this ROI (1 when it had none).
  PoseSigma estimate(const PatternBank& bank, const Measurement& m, double scale_factor) noexcept;

  int tile_px() const noexcept { return tile_; }
  double calibration() const noexcept { return calibration_; }

 private:
  const ExactScorer& scorer_;
  int pattern_px_;
  int tile_;
  double calibration_;
  double floor_px_, floor_deg_;
  double noise_factor_;
  double angle_factor_;
  double scale_factor_;
  bool pattern_noise_;
  std::vector<double> tile_sums_;  // one tile row's g_b: (pattern_px / tile + 1) × 6
  std::vector<float> row_;         // one row's ∂T/∂x and a tile row's column sums (7): 8 × pattern_px
  const PatternBank* cached_bank_ = nullptr;  // the bank h0_cache_ belongs to
  std::vector<double> h0_cache_;              // JᵀJ (gain-free) per angle: max_angles × 36
  std::vector<std::uint8_t> h0_valid_;
};

}  // namespace sempose::pose
