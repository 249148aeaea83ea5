#include "sempose/pose/pattern_bank.hpp"

#include "sempose/pose/bicubic_rotate.hpp"
#include "sempose/pose/box_downsample.hpp"
#include "sempose/pose/prefilter.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <new>
#include <string>
#include <vector>

namespace sempose::pose {

void FftwFree::operator()(void* p) const noexcept { fftwf_free(p); }

void downsample_pattern(const float* src, int n, int factor, float* out) noexcept {
  const int m = n / factor;
  const int off = (n - m * factor) / 2;
  box_downsample<float, double, float>(src, n, off, off, factor, m, m, out);
}

std::unique_ptr<const PatternBank> PatternBank::build(const PatternBankSpec& spec, const BankLevels& levels,
                                                     std::string& why) {
  std::unique_ptr<PatternBank> bank(new PatternBank());
  if (!bank->fill(spec, levels, why)) return nullptr;
  return bank;
}

bool PatternBank::fill(const PatternBankSpec& spec, const BankLevels& levels, std::string& why) {
  const PatternImage& pattern = spec.pattern;
  const PatternImage& shape_image = spec.shape;
  const PatternMask& fine_mask = levels.fine_mask;
  const PatternMask& half_mask = levels.half_mask;
  const PatternMask& coarse_mask = levels.coarse_mask;
  FftCorrelator& half = levels.half;
  FftCorrelator& coarse = levels.coarse;
  const double step_deg = spec.angle_step_deg, coarse_step_deg = spec.coarse_step_deg;
  const int factor = spec.coarse_factor;
  size_ = pattern.width;
  const int n = size_;
  angles_ = static_cast<int>(std::lround(360.0 / step_deg));
  coarse_step_deg_ = coarse_step_deg;
  coarse_angles_ = std::max(1, static_cast<int>(std::lround(360.0 / coarse_step_deg)));
  spectrum_len_ = half.spectrum_len();
  const int h = half_mask.size_px();
  std::vector<float> halved(static_cast<std::size_t>(h) * h);
  coarse_len_ = coarse.spectrum_len();
  FftCorrelator* coarse_wide = levels.coarse_wide;
  coarse_wide_len_ = coarse_wide ? coarse_wide->spectrum_len() : 0;
  const int m = coarse_mask.size_px();

  std::vector<float> src(static_cast<std::size_t>(n) * n), raw(src.size()), small(static_cast<std::size_t>(m) * m);
  for (std::size_t i = 0; i < src.size(); ++i) src[i] = static_cast<float>(pattern.pixels[i]);
  const auto [lo, hi] = std::minmax_element(src.begin(), src.end());
  // Detail only at the pixel scale (a 1-px checkerboard) is averaged away by the prefilter's
  // binomial kernel or the 2×2 bins of the search: refused as such, not as a flat pattern.
  const char* no_contrast = *lo == *hi ? "the pattern is flat (constant grey level) inside its mask"
                                       : "the pattern has no contrast the tracker can use inside its mask: detail "
                                         "only at the pixel scale (e.g. a 1-px checkerboard) is averaged away by the "
                                         "prefilter (tracker.prefilter_passes) and the 2x2 binned search level";
  // The frame is low-passed the same way (Prefilter); filtering before rotating is the same
  // as after for this near-isotropic kernel and keeps one interpolation for all angles.
  prefilter_pattern(src.data(), n, spec.prefilter_passes);
  spatial_.assign(static_cast<std::size_t>(angles_) * n * n, 0.0f);
  spectra_.reset(static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * spectrum_len_ * angles_)), FftwFree{});
  coarse_spectra_.reset(static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * coarse_len_ * coarse_angles_)), FftwFree{});
  if (coarse_wide)
    coarse_wide_spectra_.reset(static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * coarse_wide_len_ * coarse_angles_)),
                               FftwFree{});
  if (!spectra_ || !coarse_spectra_ || (coarse_wide && !coarse_wide_spectra_)) throw std::bad_alloc();

  has_shape_ = !shape_image.empty();
  std::vector<float> shape(src.size(), 1.0f), shape_scratch(src.size());
  if (has_shape_) {
    if (shape_image.width != n || shape_image.height != n) {
      why = "the shape mask is " + std::to_string(shape_image.width) + "x" + std::to_string(shape_image.height) +
            ", the pattern " + std::to_string(n) + "x" + std::to_string(n) + "; they must be the same size";
      return false;
    }
    for (std::size_t i = 0; i < shape.size(); ++i) shape[i] = shape_image.pixels[i] != 0 ? 1.0f : 0.0f;
    dilate_disk(shape, n, spec.shape_margin_px);
  }
  std::vector<std::uint8_t> fine_in(src.size());
  support_.clear();
  support_begin_.assign(1, 0);
  support_count_.clear();
  for (int j = 0; j < angles_; ++j) {
    float* p = spatial_.data() + static_cast<std::size_t>(j) * n * n;
    rotate_pattern(src.data(), n, j * step_deg, raw.data());
    std::copy(raw.begin(), raw.end(), p);
    downsample_pattern(raw.data(), n, 2, halved.data());
    // The shape mask applies to the exact full-resolution scores (the fit); the binned and
    // coarse levels that only locate the peak keep the whole circle: a silhouette's outline
    // at ×2 or ×8 is too thin a support to find it reliably (measured: the needle was
    // acquired elsewhere at margins below 6 px).
    std::int64_t count = fine_mask.count();
    if (has_shape_) {
      count = turned_support(shape, n, j * step_deg, fine_mask.bitmap(), shape_scratch, fine_in);
    } else {
      std::copy_n(fine_mask.bitmap(), fine_in.size(), fine_in.begin());
    }
    if (!normalize_pattern(p, n, fine_in.data()) || !normalize_pattern(halved.data(), half_mask)) {
      why = has_shape_ && count < 64 ? "the shape mask leaves under 64 pixels inside the pattern circle" : no_contrast;
      return false;
    }
    const std::vector<MaskBand> bands = has_shape_ ? bands_of(fine_in.data(), n) : fine_mask.bands();
    support_.insert(support_.end(), bands.begin(), bands.end());
    support_begin_.push_back(support_.size());
    support_count_.push_back(count);
    half.make_spectrum(halved.data(), spectra_.get() + static_cast<std::size_t>(j) * spectrum_len_);
  }
  for (int k = 0; k < coarse_angles_; ++k) {
    rotate_pattern(src.data(), n, k * coarse_step_deg, raw.data());
    downsample_pattern(raw.data(), n, factor, small.data());
    if (!normalize_pattern(small.data(), coarse_mask)) {
      why = "the pattern is flat after downsampling by search_downsample";
      return false;
    }
    coarse.make_spectrum(small.data(), coarse_spectra_.get() + static_cast<std::size_t>(k) * coarse_len_);
    if (coarse_wide)
      coarse_wide->make_spectrum(small.data(), coarse_wide_spectra_.get() + static_cast<std::size_t>(k) * coarse_wide_len_);
  }
  return true;
}

std::unique_ptr<const PatternBank> PatternBank::with_support(const PatternBank& base,
                                                            const std::vector<std::uint8_t>& support, std::string& why) {
  const int n = base.size_;
  if (support.size() != static_cast<std::size_t>(n) * n) {
    why = "the support is not pattern-sized";
    return nullptr;
  }
  std::unique_ptr<PatternBank> bank(new PatternBank());
  PatternBank& b = *bank;
  b.size_ = n;
  b.angles_ = base.angles_;
  b.coarse_angles_ = base.coarse_angles_;
  b.coarse_step_deg_ = base.coarse_step_deg_;
  b.spectrum_len_ = base.spectrum_len_;
  b.coarse_len_ = base.coarse_len_;
  b.coarse_wide_len_ = base.coarse_wide_len_;
  b.spectra_ = base.spectra_;
  b.coarse_spectra_ = base.coarse_spectra_;
  b.coarse_wide_spectra_ = base.coarse_wide_spectra_;
  b.has_shape_ = true;
  b.spatial_ = base.spatial_;
  b.support_begin_.assign(1, 0);
  const double c = (n - 1) / 2.0;
  const double step_deg = 360.0 / b.angles_;
  std::vector<std::uint8_t> in(support.size());
  for (int j = 0; j < b.angles_; ++j) {
    // Angle j's copy shows source offset M·d at output offset d (bicubic_rotate's map).
    const double rad = j * step_deg * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
    std::fill(in.begin(), in.end(), 0);
    for (int k = base.support_begin_[j]; k < static_cast<int>(base.support_begin_[j + 1]); ++k) {
      const MaskBand& band = base.support_[static_cast<std::size_t>(k)];
      for (int y = band.y0; y <= band.y1; ++y)
        for (int x = band.x0; x <= band.x1; ++x) {
          const double dx = x - c, dy = y - c;
          const int sx = static_cast<int>(std::lround(c + dx * cs - dy * sn));
          const int sy = static_cast<int>(std::lround(c + dx * sn + dy * cs));
          if (sx >= 0 && sy >= 0 && sx < n && sy < n && support[static_cast<std::size_t>(sy) * n + sx])
            in[static_cast<std::size_t>(y) * n + x] = 1;
        }
    }
    std::int64_t count = 0;
    for (std::uint8_t v : in) count += v;
    float* p = b.spatial_.data() + static_cast<std::size_t>(j) * n * n;
    if (count < 64 || !normalize_pattern(p, n, in.data())) {
      why = "the learned support leaves " + std::to_string(count) + " pixels (or a flat pattern) at angle " +
            std::to_string(j * step_deg) + " deg";
      return nullptr;
    }
    const std::vector<MaskBand> bands = bands_of(in.data(), n);
    b.support_.insert(b.support_.end(), bands.begin(), bands.end());
    b.support_begin_.push_back(b.support_.size());
    b.support_count_.push_back(count);
  }
  return bank;
}

double PatternBank::mean_support_count() const noexcept {
  double s = 0;
  for (std::int64_t c : support_count_) s += static_cast<double>(c);
  return support_count_.empty() ? 0.0 : s / static_cast<double>(support_count_.size());
}

std::size_t PatternBank::memory_bytes() const noexcept {
  return spatial_.size() * sizeof(float) + sizeof(Complex) * (spectrum_len_ * angles_ + (coarse_len_ + coarse_wide_len_) * coarse_angles_) +
         support_.size() * sizeof(MaskBand) + support_begin_.size() * sizeof(std::size_t) +
         support_count_.size() * sizeof(std::int64_t);
}

}  // namespace sempose::pose
