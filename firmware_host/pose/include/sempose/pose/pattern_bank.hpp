// The rotated pattern bank of one pattern set, built once from a PatternBankSpec and immutable
// after: every angle step's rotated copy (one interpolation — bicubic, Keys a = −0.5 — for
// every angle including 0°), prefiltered, masked, zero-mean, unit norm, kept at full
// resolution for the exact scorer; the same copy 2×2-binned with its spectrum at the
// half-resolution FFT size (where the whole ROI is correlated); plus the coarse copies (box
// ×search_downsample) and their spectra for the start search (one set per coarse FFT size:
// the scanned field's, and the enlarged one of the search's levels below 1 when it differs).
// With a shape mask (the target's own pixels, e.g. a needle without the background around
// it), every full-resolution copy's support is the mask turned with it, inside the circle:
// static clutter under the pattern's rim then stays out of the exact scores and the fit (it
// does not move with the target and pulled poses by up to 0.3 px / 0.4° as the target
// turned). The binned and coarse copies keep the circle (they only locate the peak).
#pragma once

#include <complex>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/pattern_image.hpp"
#include "sempose/pose/pattern_support.hpp"

namespace sempose::pose {

// Box-downsamples the central (size/factor·factor)² block of a size×size pattern.
void downsample_pattern(const float* src, int size, int factor, float* out) noexcept;

struct FftwFree {
  void operator()(void* p) const noexcept;
};

// What a bank is built from.
struct PatternBankSpec {
  PatternImage pattern;          // square
  PatternImage shape;            // pattern-sized, non-zero = the target's pixels; empty = the whole circle
  double shape_margin_px = 0;    // the shape grown by this much
  int prefilter_passes = 0;      // the frame's prefilter, applied to the pattern too
  double angle_step_deg = 1.0;   // must divide 360
  double coarse_step_deg = 20;   // start-search angles
  int coarse_factor = 8;         // start-search downsample
};

// The masks and FFT correlators a bank's copies are cut and transformed for (the tracker's).
struct BankLevels {
  const PatternMask& fine_mask;
  const PatternMask& half_mask;
  FftCorrelator& half;
  const PatternMask& coarse_mask;
  FftCorrelator& coarse;
  FftCorrelator* coarse_wide = nullptr;  // the search's levels below 1, when sized apart
};

class PatternBank {
 public:
  using Complex = FftCorrelator::Complex;
  // Setup: nullptr (and why) when the pattern is flat under the mask at some angle or the
  // shape does not fit the pattern.
  static std::unique_ptr<const PatternBank> build(const PatternBankSpec& spec, const BankLevels& levels,
                                                  std::string& why);
  // Setup or worker thread (allocates, no FFT): a bank like `base` whose full-resolution
  // supports are cut to `support` (size_px², in the pattern's own frame, 1 = keep), turned with
  // each angle (nearest neighbour) and intersected with base's support; the pattern copies are
  // renormalised over the new support (ZNCC normalisation is affine, so renormalising base's
  // copies equals normalising the raw rotations). The binned and coarse spectra are base's,
  // shared. nullptr (and why) when an angle keeps under 64 pixels or is flat.
  // With `refined` (size_px², prefiltered, the pattern's own frame: the learned template), every
  // angle's copy is that template turned (the bank's bicubic, 360 rotations: ~0.1–0.3 s, worker
  // side) instead of base's, normalised over the same support; the pattern-noise Gram and
  // variance are base's × noise_factor (the refined template's noise variance over the
  // recorded one's). The binned and coarse spectra stay base's (they only locate the peak).
  static std::unique_ptr<const PatternBank> with_support(const PatternBank& base, const std::vector<std::uint8_t>& support,
                                                         std::string& why, const float* refined = nullptr,
                                                         double noise_factor = 1.0);
  // Mean pixel count of the angles' supports.
  double mean_support_count() const noexcept;

  int angles() const noexcept { return angles_; }
  int coarse_angles() const noexcept { return coarse_angles_; }
  int size_px() const noexcept { return size_; }
  const float* pattern(int j) const noexcept { return spatial_.data() + static_cast<std::size_t>(j) * size_ * size_; }
  const Complex* spectrum(int j) const noexcept { return spectra_.get() + static_cast<std::size_t>(j) * spectrum_len_; }
  const Complex* coarse_spectrum(int k) const noexcept {
    return coarse_spectra_.get() + static_cast<std::size_t>(k) * coarse_len_;
  }
  // For BankLevels::coarse_wide's transform size (null when the bank was built without one).
  const Complex* coarse_wide_spectrum(int k) const noexcept {
    return coarse_wide_spectra_ ? coarse_wide_spectra_.get() + static_cast<std::size_t>(k) * coarse_wide_len_ : nullptr;
  }
  double coarse_angle_deg(int k) const noexcept { return k * coarse_step_deg_; }
  // Angle j's support at full resolution (pattern(j) is zero outside it): its bands and pixel count.
  const MaskBand* support_bands(int j) const noexcept { return support_.data() + support_begin_[static_cast<std::size_t>(j)]; }
  int support_band_count(int j) const noexcept {
    return static_cast<int>(support_begin_[static_cast<std::size_t>(j) + 1] - support_begin_[static_cast<std::size_t>(j)]);
  }
  std::int64_t support_count(int j) const noexcept { return support_count_[static_cast<std::size_t>(j)]; }
  bool has_shape() const noexcept { return has_shape_; }
  std::size_t memory_bytes() const noexcept;

  // The recorded pattern's own noise, measured at build on the raw pattern (line_correlated_noise
  // over the whole square: no knowledge of how it was recorded): its variance per raw pixel and
  // its correlation along the line. Per angle, the expected Gram matrix (kNoiseParams², in the
  // σ stage's order x, y, φ, scale, gain, offset; offset's row and column 0) of that noise's
  // share of the σ stage's Jacobian columns, in the copy's units: what the noise's own gradients
  // add to JᵀJ (pose_uncertainty.cpp takes it out). Found by running one noise field of the
  // measured variance and correlation through the copies' prefilter, rotations, supports and
  // normalisation (φ's row and column: pattern_bank.cpp). nullptr when not measured (0 noise
  // read, or a pattern over 512 px).
  static constexpr int kNoiseParams = 6;
  const double* noise_gram(int j) const noexcept {
    return noise_gram_.empty() ? nullptr : noise_gram_.data() + static_cast<std::size_t>(j) * kNoiseParams * kNoiseParams;
  }
  double pattern_noise_var() const noexcept { return pattern_noise_var_; }
  double pattern_noise_rho() const noexcept { return pattern_noise_rho_; }

  // The background plane's regressors (SubpixelFit): with the copy t, the window's x and y (in
  // pattern widths from the centre), each centred over the support. Per angle: their means and
  // the Gram of (t, x, y) (Σt² = 1, Σt = 0).
  struct PlaneGram {
    double mean_x = 0, mean_y = 0;
    double g[3][3] = {};
    // G's lower Cholesky factor, made at setup; not factored when G is not positive definite
    // (a support without extent in x or y). The sub-pixel fit and the σ stage solve with it.
    double chol[3][3] = {};
    bool factored = false;
    // RT: w = L⁻¹b, so |w|² = bᵀG⁻¹b (b: the window's products with t, x, y); false unfactored.
    bool whiten(const double b[3], double w[3]) const noexcept;
    // RT: z = G⁻¹b, the least-squares gain of t and slopes of x and y; false unfactored.
    bool solve(const double b[3], double z[3]) const noexcept;
  };
  const PlaneGram& plane_gram(int j) const noexcept { return plane_gram_[static_cast<std::size_t>(j)]; }

 private:
  PatternBank() = default;
  bool fill(const PatternBankSpec& spec, const BankLevels& levels, std::string& why);
  // Setup: pattern_noise_var_ and noise_gram_ of this bank (norm: each copy's factor from the
  // prefiltered, turned pattern to the copy, i.e. 1 / its norm over the support).
  void model_pattern_noise(const PatternImage& pattern, int prefilter_passes, const std::vector<double>& norm);
  // Setup: plane_gram_ from the copies and their supports.
  void measure_plane_grams();

  int size_ = 0, angles_ = 0, coarse_angles_ = 0;
  double coarse_step_deg_ = 20;
  std::size_t spectrum_len_ = 0, coarse_len_ = 0, coarse_wide_len_ = 0;
  std::vector<float> spatial_;
  bool has_shape_ = false;
  std::vector<MaskBand> support_;            // every angle's support bands, one after another
  std::vector<std::size_t> support_begin_;   // angles_ + 1 offsets into support_
  std::vector<std::int64_t> support_count_;  // pixels per angle's support
  double pattern_noise_var_ = 0, pattern_noise_rho_ = 0;
  std::vector<double> noise_gram_;  // angles_ × kNoiseParams², empty: not measured
  std::vector<PlaneGram> plane_gram_;  // per angle
  // Shared with banks made by with_support() (the spectra do not depend on the fine support).
  std::shared_ptr<Complex> spectra_;
  std::shared_ptr<Complex> coarse_spectra_;
  std::shared_ptr<Complex> coarse_wide_spectra_;
};

}  // namespace sempose::pose
