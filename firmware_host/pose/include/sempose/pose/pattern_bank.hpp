// The rotated pattern bank of one pattern set: every angle step's rotated copy (one
// interpolation — bicubic, Keys a = −0.5 — for every angle including 0°), prefiltered,
// masked, zero-mean, unit norm, kept at full resolution for the exact local ZNCC; the same
// copy 2×2-binned with its spectrum at the half-resolution FFT size (where the whole ROI is
// correlated); plus the coarse copies (box ×8) and their spectra for the start search.
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

#include "sempose/hal/image.hpp"
#include "sempose/pose/zncc.hpp"

namespace sempose::pose {

// Rotates src (size×size, row-major) by phi_deg about its centre, counter-clockwise on the
// screen (README: Conventions), bicubic; samples falling outside are clamped to the border.
void rotate_pattern(const float* src, int size, double phi_deg, float* out) noexcept;

// Box-downsamples the central (size/factor·factor)² block of a size×size pattern.
void downsample_pattern(const float* src, int size, int factor, float* out) noexcept;

struct FftwFree {
  void operator()(void* p) const noexcept;
};

class PatternBank {
 public:
  using Complex = ZnccCorrelator::Complex;
  // Returns false (and why) when the pattern is flat under the mask at some angle.
  // shape: pattern-sized, non-zero = the target's pixels, grown by shape_margin_px; empty =
  // the whole circle.
  bool build(const hal::Image& pattern, const hal::Image& shape, double shape_margin_px, int prefilter_passes,
             double angle_step_deg,
             const PatternMask& fine_mask,
             const PatternMask& half_mask, ZnccCorrelator& half, double coarse_step_deg, int factor, const PatternMask& coarse_mask,
             ZnccCorrelator& coarse, std::string& why);

  int angles() const noexcept { return angles_; }
  int coarse_angles() const noexcept { return coarse_angles_; }
  const float* pattern(int j) const noexcept { return spatial_.data() + static_cast<std::size_t>(j) * size_ * size_; }
  const Complex* spectrum(int j) const noexcept { return spectra_.get() + static_cast<std::size_t>(j) * spectrum_len_; }
  const Complex* coarse_spectrum(int k) const noexcept {
    return coarse_spectra_.get() + static_cast<std::size_t>(k) * coarse_len_;
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

 private:
  int size_ = 0, angles_ = 0, coarse_angles_ = 0;
  double coarse_step_deg_ = 20;
  std::size_t spectrum_len_ = 0, coarse_len_ = 0;
  std::vector<float> spatial_;
  bool has_shape_ = false;
  std::vector<MaskBand> support_;            // every angle's support bands, one after another
  std::vector<std::size_t> support_begin_;   // angles_ + 1 offsets into support_
  std::vector<std::int64_t> support_count_;  // pixels per angle's support
  std::unique_ptr<Complex[], FftwFree> spectra_;
  std::unique_ptr<Complex[], FftwFree> coarse_spectra_;
};

}  // namespace sempose::pose
