#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/simd_clones.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>

#include "sempose/rt/alloc_counter.hpp"

namespace sempose::pose {

namespace {
// FFTW's planner is not thread-safe; execution is. Setup may run for several targets at once.
std::mutex& planner_mutex() {
  static std::mutex m;
  return m;
}

// Hot loops, compiled for AVX-512, AVX2 and the baseline and picked at load time (ifunc),
// so one binary runs everywhere and uses the wide vectors where the CPU has them.

SEMPOSE_CLONES void add_band_sums(const std::int64_t* __restrict t1, const std::int64_t* __restrict u1,
                                  const std::int64_t* __restrict t2, const std::int64_t* __restrict u2, int span,
                                  int n, std::int64_t* __restrict w1, std::int64_t* __restrict w2) noexcept {
  for (int ux = 0; ux < n; ++ux) {
    w1[ux] += u1[ux + span] - u1[ux] - t1[ux + span] + t1[ux];
    w2[ux] += u2[ux + span] - u2[ux] - t2[ux + span] + t2[ux];
  }
}

SEMPOSE_CLONES void inverse_sigma(const std::int64_t* __restrict w1, const std::int64_t* __restrict w2, int n,
                                  double count, double sqrt_count, double flat_limit,
                                  float* __restrict inv) noexcept {
  for (int ux = 0; ux < n; ++ux) {
    // n·Σf² − (Σf)² in double: its rounding (~1e-16 relative) is far below flat_limit.
    const double s1 = static_cast<double>(w1[ux]);
    const double d = count * static_cast<double>(w2[ux]) - s1 * s1;
    inv[ux] = d > flat_limit ? static_cast<float>(sqrt_count / std::sqrt(d)) : 0.0f;
  }
}

SEMPOSE_CLONES void multiply_spectra(const float* __restrict a, const float* __restrict b, float* __restrict p,
                                     std::size_t len) noexcept {
  // Hand-written complex product: std::complex operator* calls __mulsc3 (NaN handling).
  for (std::size_t i = 0; i < len; ++i) {
    const float ar = a[2 * i], ai = a[2 * i + 1], br = b[2 * i], bi = b[2 * i + 1];
    p[2 * i] = ar * br - ai * bi;
    p[2 * i + 1] = ar * bi + ai * br;
  }
}

SEMPOSE_CLONES void scale_clamp(const float* __restrict c, const float* __restrict inv, float* __restrict o,
                                int n) noexcept {
  for (int ux = 0; ux < n; ++ux) o[ux] = std::clamp(c[ux] * inv[ux], -1.0f, 1.0f);
}

}  // namespace

int good_fft_size(int n) noexcept {
  for (int m = std::max(n, 1);; ++m) {
    int r = m;
    for (int p : {2, 3, 5}) {
      while (r % p == 0) r /= p;
    }
    if (r == 1) return m;
  }
}

FftCorrelator::FftCorrelator(int fft_w, int fft_h, const PatternMask& mask)
    : fft_w_(fft_w), fft_h_(fft_h), mask_(mask), tables_(fft_w, fft_h) {
  // Some FFTW plans (buffered or indirect solvers) malloc scratch inside fftwf_execute, and
  // for some sizes FFTW has no plan at all once those solvers are excluded (the planner
  // returns NULL). Try the flag sets from fastest to most restricted; a plan is taken only
  // when both directions exist and one execution with the heap counter armed allocated
  // nothing. When no flag set gives such a plan at a size, the next larger 2,3,5-smooth
  // size is tried: the region is zero-padded anyway, so a larger transform gives the same
  // scores. Checked here, at setup, so the loop's zero-allocation guarantee never depends
  // on what the planner happened to pick, and a NULL plan is never executed.
  static constexpr unsigned kFlagSets[] = {FFTW_MEASURE, FFTW_MEASURE | FFTW_NO_BUFFERING,
                                           FFTW_MEASURE | FFTW_NO_BUFFERING | FFTW_NO_INDIRECT_OP,
                                           FFTW_ESTIMATE | FFTW_NO_BUFFERING | FFTW_NO_INDIRECT_OP};
  constexpr int kSizeAttempts = 6;
  const int want_w = std::max(1, fft_w), want_h = std::max(1, fft_h);
  bool found = false;
  for (int attempt = 0; attempt < kSizeAttempts && !found; ++attempt) {
    if (attempt > 0) {
      fft_w_ = good_fft_size(fft_w_ + 1);
      fft_h_ = good_fft_size(fft_h_ + 1);
    } else {
      fft_w_ = want_w;
      fft_h_ = want_h;
    }
    allocate_buffers();
    for (unsigned flags : kFlagSets) {
      if (make_plans(flags) && !execution_allocates()) {
        found = true;
        break;
      }
    }
  }
  execute_allocates_ = !found;
  if (!found) {
    // No allocation-free plan anywhere: keep the requested size with FFTW's default
    // solvers (which always plan) and let setup report that the loop may allocate.
    fft_w_ = want_w;
    fft_h_ = want_h;
    allocate_buffers();
    if (!make_plans(FFTW_ESTIMATE)) throw std::runtime_error("FFTW could not plan a " + std::to_string(fft_w_) + "x" +
                                                             std::to_string(fft_h_) + " transform");
  }
  if (fft_w_ != want_w || fft_h_ != want_h) tables_ = SummedAreaTables(fft_w_, fft_h_);
  const std::size_t real_len = static_cast<std::size_t>(fft_w_) * fft_h_;
  std::memset(image_, 0, sizeof(float) * real_len);
  std::memset(corr_, 0, sizeof(float) * real_len);
  std::memset(static_cast<void*>(image_spec_), 0, sizeof(Complex) * spectrum_len());
  row1_.assign(static_cast<std::size_t>(fft_w_), 0);
  row2_.assign(static_cast<std::size_t>(fft_w_), 0);
  inv_sigma_.assign(real_len, 0.0f);
}

void FftCorrelator::allocate_buffers() {
  destroy_plans();
  fftwf_free(image_);
  fftwf_free(corr_);
  fftwf_free(image_spec_);
  fftwf_free(product_);
  const std::size_t real_len = static_cast<std::size_t>(fft_w_) * fft_h_;
  image_ = static_cast<float*>(fftwf_malloc(sizeof(float) * real_len));
  corr_ = static_cast<float*>(fftwf_malloc(sizeof(float) * real_len));
  image_spec_ = static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * spectrum_len()));
  product_ = static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * spectrum_len()));
  if (!image_ || !corr_ || !image_spec_ || !product_) throw std::bad_alloc();
}

void FftCorrelator::destroy_plans() noexcept {
  std::lock_guard<std::mutex> lock(planner_mutex());
  if (plan_forward_) fftwf_destroy_plan(static_cast<fftwf_plan>(plan_forward_));
  if (plan_inverse_) fftwf_destroy_plan(static_cast<fftwf_plan>(plan_inverse_));
  plan_forward_ = plan_inverse_ = nullptr;
}

bool FftCorrelator::make_plans(unsigned flags) {
  destroy_plans();
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    plan_forward_ = fftwf_plan_dft_r2c_2d(fft_h_, fft_w_, image_, reinterpret_cast<fftwf_complex*>(image_spec_), flags);
    plan_inverse_ = fftwf_plan_dft_c2r_2d(fft_h_, fft_w_, reinterpret_cast<fftwf_complex*>(product_), corr_, flags);
  }
  if (plan_forward_ && plan_inverse_) return true;
  destroy_plans();
  return false;
}

bool FftCorrelator::execution_allocates() noexcept {
  // FFTW_MEASURE planning overwrites the arrays: run on zeros.
  std::memset(image_, 0, sizeof(float) * static_cast<std::size_t>(fft_w_) * fft_h_);
  std::memset(static_cast<void*>(product_), 0, sizeof(Complex) * spectrum_len());
  rt::alloc::ScopedArm arm;
  const std::uint64_t before = rt::alloc::this_thread_allocations();
  fftwf_execute(static_cast<fftwf_plan>(plan_forward_));
  fftwf_execute(static_cast<fftwf_plan>(plan_inverse_));
  return rt::alloc::this_thread_allocations() != before;
}

FftCorrelator::~FftCorrelator() {
  destroy_plans();
  fftwf_free(image_);
  fftwf_free(corr_);
  fftwf_free(image_spec_);
  fftwf_free(product_);
}

std::size_t FftCorrelator::buffer_bytes() const noexcept {
  const std::size_t real_len = static_cast<std::size_t>(fft_w_) * fft_h_;
  return real_len * sizeof(float) * 3 + spectrum_len() * sizeof(Complex) * 2 +
         tables_.memory_bytes();
}

void FftCorrelator::make_spectrum(const float* pattern, Complex* out) noexcept {
  const int n = mask_.size_px();
  std::memset(image_, 0, sizeof(float) * static_cast<std::size_t>(fft_w_) * fft_h_);
  for (int y = 0; y < n; ++y) std::memcpy(image_ + y * fft_w_, pattern + y * n, sizeof(float) * n);
  fftwf_execute_dft_r2c(static_cast<fftwf_plan>(plan_forward_), image_, reinterpret_cast<fftwf_complex*>(out));
  const float scale = 1.0f / static_cast<float>(fft_w_ * fft_h_);
  for (std::size_t i = 0; i < spectrum_len(); ++i) out[i] = std::conj(out[i]) * scale;
  std::memset(image_, 0, sizeof(float) * static_cast<std::size_t>(fft_w_) * fft_h_);
}

bool FftCorrelator::load(const std::uint16_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept {
  return load_impl(pixels, w, h, stride);
}
bool FftCorrelator::load(const std::int32_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept {
  return load_impl(pixels, w, h, stride);
}

template <typename T>
bool FftCorrelator::load_impl(const T* px, int w, int h, std::ptrdiff_t stride) noexcept {
  const int n = mask_.size_px();
  w = std::clamp(w, 0, fft_w_);
  h = std::clamp(h, 0, fft_h_);
  w_ = w;
  h_ = h;
  valid_w_ = std::max(0, w - n + 1);
  valid_h_ = std::max(0, h - n + 1);
  if (valid_w_ == 0 || valid_h_ == 0) return false;

  // Exact integer summed-area tables (no cancellation in Σf² − (Σf)²/n, flat is exactly 0).
  tables_.build(px, w, h, stride);
  const std::size_t sw = tables_.row_stride();
  const std::int64_t* s1 = tables_.sums();
  const std::int64_t* s2 = tables_.square_sums();
  const std::int64_t total1 = tables_.total();
  const std::int64_t total2 = tables_.total_squares();
  const std::int64_t area = static_cast<std::int64_t>(w) * h;
  // Whole region flat (std below half a grey level): nothing to correlate.
  const bool region_flat = static_cast<long double>(area) * total2 - static_cast<long double>(total1) * total1 <
                           0.25L * area * area;

  // Region minus its mean as float for the FFT (the pattern is zero-mean, so the offset
  // does not change the numerator but keeps float magnitudes small).
  const float mean = static_cast<float>(static_cast<double>(total1) / static_cast<double>(area));
  for (int y = 0; y < h; ++y) {
    const T* row = px + y * stride;
    float* dst = image_ + y * fft_w_;
    for (int x = 0; x < w; ++x) dst[x] = static_cast<float>(row[x]) - mean;
    for (int x = w; x < fft_w_; ++x) dst[x] = 0.0f;
  }
  for (int y = h; y < fft_h_; ++y) std::memset(image_ + y * fft_w_, 0, sizeof(float) * fft_w_);

  // Window sums under the mask for every displacement: 4 look-ups per band, vectorised over x.
  const std::int64_t count = mask_.count();
  const double sqrt_count = std::sqrt(static_cast<double>(count));
  const double flat_limit = 0.25 * static_cast<double>(count) * static_cast<double>(count);
  for (int uy = 0; uy < valid_h_; ++uy) {
    std::int64_t* w1 = row1_.data();
    std::int64_t* w2 = row2_.data();
    for (int ux = 0; ux < valid_w_; ++ux) w1[ux] = w2[ux] = 0;
    for (const MaskBand& b : mask_.bands()) {
      const std::int64_t* t1 = s1 + (uy + b.y0) * sw + b.x0;
      const std::int64_t* u1 = s1 + (uy + b.y1 + 1) * sw + b.x0;
      const std::int64_t* t2 = s2 + (uy + b.y0) * sw + b.x0;
      const std::int64_t* u2 = s2 + (uy + b.y1 + 1) * sw + b.x0;
      add_band_sums(t1, u1, t2, u2, b.x1 - b.x0 + 1, valid_w_, w1, w2);
    }
    inverse_sigma(w1, w2, valid_w_, static_cast<double>(count), sqrt_count, flat_limit,
                  inv_sigma_.data() + static_cast<std::size_t>(uy) * valid_w_);
  }
  fftwf_execute_dft_r2c(static_cast<fftwf_plan>(plan_forward_), image_,
                        reinterpret_cast<fftwf_complex*>(image_spec_));
  return !region_flat;
}

void FftCorrelator::correlate(const Complex* spectrum, float* out) noexcept {
  multiply_spectra(reinterpret_cast<const float*>(image_spec_), reinterpret_cast<const float*>(spectrum),
                   reinterpret_cast<float*>(product_), spectrum_len());
  fftwf_execute_dft_c2r(static_cast<fftwf_plan>(plan_inverse_), reinterpret_cast<fftwf_complex*>(product_), corr_);
  for (int uy = 0; uy < valid_h_; ++uy) {
    const float* c = corr_ + static_cast<std::size_t>(uy) * fft_w_;
    const float* inv = inv_sigma_.data() + static_cast<std::size_t>(uy) * valid_w_;
    scale_clamp(c, inv, out + static_cast<std::size_t>(uy) * valid_w_, valid_w_);
  }
}

}  // namespace sempose::pose
