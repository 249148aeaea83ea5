// Masked zero-mean normalized cross-correlation of one pattern size against a whole region at
// once, up to a fixed FFT size: the numerator via FFTW single precision (r2c forward once per
// region, one c2r inverse per pattern spectrum), the normalisation from exact integer
// summed-area tables of f and f² over the mask bands (Lewis 1995 running sums, made exact and
// mask-aware). Flat windows score 0; scores are clamped to [-1, 1]. It locates peaks (the
// binned ROI level, the coarse full-field level); the exact full-resolution score of one
// displacement is the ExactScorer's job.
// Construction and make_spectrum() are setup (allocate, plan); load/correlate are RT.
#pragma once

#include <complex>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sempose/pose/pattern_support.hpp"
#include "sempose/pose/summed_area_table.hpp"

namespace sempose::pose {

// Smallest n' >= n whose prime factors are 2, 3 and 5 only (sizes FFTW is fast at).
int good_fft_size(int n) noexcept;

class FftCorrelator {
 public:
  using Complex = std::complex<float>;

  // fft_w × fft_h is the smallest transform wanted; the correlator may pick the next larger
  // 2,3,5-smooth size when FFTW has no allocation-free plan at that size (fft_w()/fft_h()
  // tell which). Throws only when FFTW cannot plan at all.
  FftCorrelator(int fft_w, int fft_h, const PatternMask& mask);
  ~FftCorrelator();
  FftCorrelator(const FftCorrelator&) = delete;
  FftCorrelator& operator=(const FftCorrelator&) = delete;

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

 private:
  template <typename T>
  bool load_impl(const T* pixels, int w, int h, std::ptrdiff_t stride) noexcept;
  void allocate_buffers();
  void destroy_plans() noexcept;
  bool make_plans(unsigned flags);     // false (and no plan kept) when FFTW has none
  bool execution_allocates() noexcept; // one forward + inverse run with the heap counter armed

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
  SummedAreaTables tables_;                // of the loaded region
  std::vector<std::int64_t> row1_, row2_;  // per-row window sums scratch (valid_w)
  std::vector<float> inv_sigma_;           // sqrt(n)/sqrt(n·Σf² − (Σf)²) per displacement, 0 if flat
};

}  // namespace sempose::pose
