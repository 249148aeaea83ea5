// Masked zero-mean normalized cross-correlation of one pattern size against image regions up
// to a fixed FFT size. Numerator via FFTW single precision (r2c forward once per image, one
// c2r inverse per pattern spectrum); normalisation with exact integer summed-area tables of
// f and f² over the mask (Lewis 1995 running sums, made exact and mask-aware: the mask is a
// union of horizontal bands inscribed in the pattern's circle, so each window sum costs four
// look-ups per band). Flat windows score 0; scores are clamped to [-1, 1].
// Construction and make_spectrum() are setup (allocate, plan); load/correlate/score_at are RT.
#pragma once

#include <complex>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace sempose::pose {

// Smallest n' >= n whose prime factors are 2, 3 and 5 only (sizes FFTW is fast at).
int good_fft_size(int n) noexcept;

struct MaskBand {
  int y0, y1;  // inclusive pattern rows
  int x0, x1;  // inclusive pattern columns
};

// The pattern's support: its inscribed circle as a stack of bands (or the full square).
// inset_px shrinks the circle's radius: the pattern's outer pixels are not trustworthy after
// setup-time filtering and rotation (edges replicated, bicubic support clamped), and a mask
// that reaches them compares made-up pixels with real ones — an offset that turns with the
// target.
class PatternMask {
 public:
  PatternMask(int size_px, bool circular, int bands_per_half = 8, double inset_px = 0);
  int size_px() const noexcept { return size_; }
  std::int64_t count() const noexcept { return count_; }
  const std::vector<MaskBand>& bands() const noexcept { return bands_; }
  bool inside(int x, int y) const noexcept { return bitmap_[static_cast<std::size_t>(y * size_ + x)] != 0; }
  const std::uint8_t* bitmap() const noexcept { return bitmap_.data(); }

 private:
  int size_;
  std::int64_t count_ = 0;
  std::vector<MaskBand> bands_;
  std::vector<std::uint8_t> bitmap_;
};

// Makes a pattern ready for correlation: zero outside the mask, zero mean and unit L2 norm
// inside. Returns false when the pattern is flat under the mask (or the mask is empty).
bool normalize_pattern(float* pattern, const PatternMask& mask) noexcept;
// The same for any support: inside[size_px²], non-zero = pattern pixel.
bool normalize_pattern(float* pattern, int size_px, const std::uint8_t* inside) noexcept;

// A support bitmap (size_px², non-zero = inside) as row runs, consecutive rows with the same
// run merged into one band: window sums over it cost four summed-area look-ups per band.
std::vector<MaskBand> bands_of(const std::uint8_t* inside, int size_px);

class ZnccCorrelator {
 public:
  using Complex = std::complex<float>;

  ZnccCorrelator(int fft_w, int fft_h, const PatternMask& mask);
  ~ZnccCorrelator();
  ZnccCorrelator(const ZnccCorrelator&) = delete;
  ZnccCorrelator& operator=(const ZnccCorrelator&) = delete;

  int fft_w() const noexcept { return fft_w_; }
  int fft_h() const noexcept { return fft_h_; }
  int pattern_px() const noexcept { return mask_.size_px(); }
  std::size_t spectrum_len() const noexcept { return static_cast<std::size_t>(fft_h_) * (fft_w_ / 2 + 1); }
  std::size_t buffer_bytes() const noexcept;
  // True when no FFTW plan could be found whose execution is allocation-free (setup reports it).
  bool execute_allocates() const noexcept { return execute_allocates_; }

  // Setup: conj(FFT(pattern zero-padded)) / (fft_w·fft_h) into out[spectrum_len()].
  // pattern: P×P, already normalize_pattern()ed.
  void make_spectrum(const float* pattern, Complex* out) noexcept;

  // RT: loads a w×h region (row stride in elements); pattern_px <= w <= fft_w, same for h.
  // Forward FFT + window sums. Returns false when the whole region is flat (then every
  // score is 0).
  bool load(const std::uint16_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept;
  bool load(const std::int32_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept;

  // Displacements of the pattern's top-left inside the loaded region.
  int valid_w() const noexcept { return valid_w_; }
  int valid_h() const noexcept { return valid_h_; }

  // RT: ZNCC for every valid displacement into out[valid_h()][valid_w()].
  void correlate(const Complex* spectrum, float* out) noexcept;
  // RT: ZNCC at one displacement by a direct dot product (pattern as for make_spectrum).
  float score_at(const float* pattern, int ux, int uy) const noexcept;

 private:
  template <typename T>
  bool load_impl(const T* pixels, int w, int h, std::ptrdiff_t stride) noexcept;

  int fft_w_, fft_h_;
  const PatternMask& mask_;
  int w_ = 0, h_ = 0, valid_w_ = 0, valid_h_ = 0;
  float* image_ = nullptr;      // fft_h × fft_w, region minus its mean, zero padded (fftwf_malloc)
  Complex* image_spec_ = nullptr;
  Complex* product_ = nullptr;
  float* corr_ = nullptr;       // c2r output
  void* plan_forward_ = nullptr;
  void* plan_inverse_ = nullptr;
  bool execute_allocates_ = false;
  std::vector<std::int64_t> sat1_, sat2_;  // (h+1)×(w+1) summed-area tables of f and f²
  std::vector<std::int64_t> row1_, row2_;  // per-row window sums scratch (valid_w)
  std::vector<float> inv_sigma_;           // sqrt(n)/sqrt(n·Σf² − (Σf)²) per displacement, 0 if flat
};

}  // namespace sempose::pose
