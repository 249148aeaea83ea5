#include "sempose/pose/zncc.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <new>

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
#define SEMPOSE_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))

SEMPOSE_CLONES void add_band_sums(const std::int64_t* __restrict t1, const std::int64_t* __restrict u1,
                                  const std::int64_t* __restrict t2, const std::int64_t* __restrict u2, int span,
                                  int n, std::int64_t* __restrict w1, std::int64_t* __restrict w2) noexcept {
  for (int ux = 0; ux < n; ++ux) {
    w1[ux] += u1[ux + span] - u1[ux] - t1[ux + span] + t1[ux];
    w2[ux] += u2[ux + span] - u2[ux] - t2[ux + span] + t2[ux];
  }
}

SEMPOSE_CLONES void add_rows(std::int64_t* __restrict a1, const std::int64_t* __restrict b1,
                             std::int64_t* __restrict a2, const std::int64_t* __restrict b2, int n) noexcept {
  for (int x = 0; x < n; ++x) {
    a1[x] += b1[x];
    a2[x] += b2[x];
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

SEMPOSE_CLONES float dot(const float* __restrict t, const float* __restrict f, int n) noexcept {
  float acc = 0.0f;
#pragma omp simd reduction(+ : acc)
  for (int x = 0; x < n; ++x) acc += t[x] * f[x];
  return acc;
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

PatternMask::PatternMask(int size_px, bool circular, int bands_per_half, double inset_px)
    : size_(size_px), bitmap_(static_cast<std::size_t>(size_px) * size_px, 0) {
  if (!circular) {
    bands_.push_back({0, size_ - 1, 0, size_ - 1});
  } else {
    // Rows are grouped by their distance from the centre; a band takes the narrowest
    // half-width of its rows so every mask pixel lies inside the circle (rotated
    // patterns have real data there) while each window sum costs only 4 look-ups per band.
    const double c = (size_ - 1) / 2.0;
    const double radius = std::max(1.0, size_ / 2.0 - inset_px);
    const int band_rows = std::max(1, (size_ / 2 + bands_per_half - 1) / bands_per_half);
    auto half_width = [&](int row) {
      const double dy = std::fabs(row - c) + 0.5;
      return std::sqrt(std::max(0.0, radius * radius - dy * dy));
    };
    int row = 0;
    while (row < size_) {
      const bool upper = row < c;
      const int key = static_cast<int>(std::fabs(row - c) / band_rows);
      int end = row;
      while (end + 1 < size_ && ((end + 1) < c) == upper &&
             static_cast<int>(std::fabs(end + 1 - c) / band_rows) == key) {
        ++end;
      }
      double hw = 1e9;
      for (int r = row; r <= end; ++r) hw = std::min(hw, half_width(r));
      const int x0 = static_cast<int>(std::ceil(c + 0.5 - hw - 1e-9));
      const int x1 = static_cast<int>(std::floor(c - 0.5 + hw + 1e-9));
      if (x0 <= x1) bands_.push_back({row, end, x0, x1});
      row = end + 1;
    }
  }
  for (const auto& b : bands_) {
    for (int y = b.y0; y <= b.y1; ++y) {
      for (int x = b.x0; x <= b.x1; ++x) bitmap_[static_cast<std::size_t>(y * size_ + x)] = 1;
    }
    count_ += static_cast<std::int64_t>(b.y1 - b.y0 + 1) * (b.x1 - b.x0 + 1);
  }
}

bool normalize_pattern(float* p, const PatternMask& mask) noexcept {
  return normalize_pattern(p, mask.size_px(), mask.bitmap());
}

bool normalize_pattern(float* p, int n, const std::uint8_t* inside) noexcept {
  double sum = 0;
  std::int64_t count = 0;
  for (int i = 0; i < n * n; ++i) {
    if (inside[i]) {
      sum += p[i];
      ++count;
    }
  }
  if (count == 0) return false;
  const double mean = sum / static_cast<double>(count);
  double ss = 0;
  for (int i = 0; i < n * n; ++i) {
    float& v = p[i];
    v = inside[i] ? static_cast<float>(v - mean) : 0.0f;
    ss += static_cast<double>(v) * v;
  }
  if (!(ss > 1e-12 * static_cast<double>(count))) return false;
  const float scale = static_cast<float>(1.0 / std::sqrt(ss));
  for (int i = 0; i < n * n; ++i) p[i] *= scale;
  return true;
}

std::vector<MaskBand> bands_of(const std::uint8_t* inside, int n) {
  std::vector<MaskBand> out;
  std::size_t prev_begin = 0, prev_end = 0;  // the previous row's bands in out
  for (int y = 0; y < n; ++y) {
    const std::size_t row_begin = out.size();
    for (int x = 0; x < n;) {
      if (!inside[y * n + x]) {
        ++x;
        continue;
      }
      int x1 = x;
      while (x1 + 1 < n && inside[y * n + x1 + 1]) ++x1;
      bool merged = false;
      for (std::size_t k = prev_begin; k < prev_end && !merged; ++k) {
        if (out[k].x0 == x && out[k].x1 == x1 && out[k].y1 == y - 1) {
          out[k].y1 = y;
          merged = true;
        }
      }
      if (!merged) out.push_back({y, y, x, x1});
      x = x1 + 1;
    }
    // Bands extended into this row stay candidates for the next one.
    prev_begin = std::min(prev_begin, row_begin);
    prev_end = out.size();
    std::size_t first_live = prev_end;
    for (std::size_t k = prev_begin; k < prev_end; ++k)
      if (out[k].y1 == y) first_live = std::min(first_live, k);
    prev_begin = first_live;
  }
  return out;
}

ZnccCorrelator::ZnccCorrelator(int fft_w, int fft_h, const PatternMask& mask)
    : fft_w_(fft_w), fft_h_(fft_h), mask_(mask) {
  const std::size_t real_len = static_cast<std::size_t>(fft_w_) * fft_h_;
  image_ = static_cast<float*>(fftwf_malloc(sizeof(float) * real_len));
  corr_ = static_cast<float*>(fftwf_malloc(sizeof(float) * real_len));
  image_spec_ = static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * spectrum_len()));
  product_ = static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * spectrum_len()));
  if (!image_ || !corr_ || !image_spec_ || !product_) throw std::bad_alloc();
  // Some FFTW plans (buffered or indirect solvers) malloc scratch inside fftwf_execute for
  // large sizes. Make a plan, run it once with the heap counter armed, and re-plan without
  // those solvers until the execution is allocation-free (checked here, at setup, so the
  // loop's zero-allocation guarantee does not depend on what the planner happened to pick).
  static constexpr unsigned kFlagSets[] = {FFTW_MEASURE, FFTW_MEASURE | FFTW_NO_BUFFERING,
                                           FFTW_MEASURE | FFTW_NO_BUFFERING | FFTW_NO_INDIRECT_OP,
                                           FFTW_ESTIMATE | FFTW_NO_BUFFERING | FFTW_NO_INDIRECT_OP};
  std::memset(image_, 0, sizeof(float) * real_len);
  std::memset(static_cast<void*>(product_), 0, sizeof(Complex) * spectrum_len());
  for (unsigned flags : kFlagSets) {
    std::lock_guard<std::mutex> lock(planner_mutex());
    if (plan_forward_) fftwf_destroy_plan(static_cast<fftwf_plan>(plan_forward_));
    if (plan_inverse_) fftwf_destroy_plan(static_cast<fftwf_plan>(plan_inverse_));
    plan_forward_ = fftwf_plan_dft_r2c_2d(fft_h_, fft_w_, image_, reinterpret_cast<fftwf_complex*>(image_spec_), flags);
    plan_inverse_ = fftwf_plan_dft_c2r_2d(fft_h_, fft_w_, reinterpret_cast<fftwf_complex*>(product_), corr_, flags);
    std::memset(image_, 0, sizeof(float) * real_len);
    std::memset(static_cast<void*>(product_), 0, sizeof(Complex) * spectrum_len());
    std::uint64_t allocs = 0;
    {
      rt::alloc::ScopedArm arm;
      const std::uint64_t before = rt::alloc::this_thread_allocations();
      fftwf_execute(static_cast<fftwf_plan>(plan_forward_));
      fftwf_execute(static_cast<fftwf_plan>(plan_inverse_));
      allocs = rt::alloc::this_thread_allocations() - before;
    }
    execute_allocates_ = allocs != 0;
    if (!execute_allocates_) break;
  }
  std::memset(image_, 0, sizeof(float) * real_len);
  std::memset(corr_, 0, sizeof(float) * real_len);
  std::memset(static_cast<void*>(image_spec_), 0, sizeof(Complex) * spectrum_len());
  const std::size_t sat_len = static_cast<std::size_t>(fft_w_ + 1) * (fft_h_ + 1);
  sat1_.assign(sat_len, 0);
  sat2_.assign(sat_len, 0);
  row1_.assign(static_cast<std::size_t>(fft_w_), 0);
  row2_.assign(static_cast<std::size_t>(fft_w_), 0);
  inv_sigma_.assign(real_len, 0.0f);
}

ZnccCorrelator::~ZnccCorrelator() {
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    if (plan_forward_) fftwf_destroy_plan(static_cast<fftwf_plan>(plan_forward_));
    if (plan_inverse_) fftwf_destroy_plan(static_cast<fftwf_plan>(plan_inverse_));
  }
  fftwf_free(image_);
  fftwf_free(corr_);
  fftwf_free(image_spec_);
  fftwf_free(product_);
}

std::size_t ZnccCorrelator::buffer_bytes() const noexcept {
  const std::size_t real_len = static_cast<std::size_t>(fft_w_) * fft_h_;
  return real_len * sizeof(float) * 3 + spectrum_len() * sizeof(Complex) * 2 +
         (sat1_.size() + sat2_.size()) * sizeof(std::int64_t);
}

void ZnccCorrelator::make_spectrum(const float* pattern, Complex* out) noexcept {
  const int n = mask_.size_px();
  std::memset(image_, 0, sizeof(float) * static_cast<std::size_t>(fft_w_) * fft_h_);
  for (int y = 0; y < n; ++y) std::memcpy(image_ + y * fft_w_, pattern + y * n, sizeof(float) * n);
  fftwf_execute_dft_r2c(static_cast<fftwf_plan>(plan_forward_), image_, reinterpret_cast<fftwf_complex*>(out));
  const float scale = 1.0f / static_cast<float>(fft_w_ * fft_h_);
  for (std::size_t i = 0; i < spectrum_len(); ++i) out[i] = std::conj(out[i]) * scale;
  std::memset(image_, 0, sizeof(float) * static_cast<std::size_t>(fft_w_) * fft_h_);
}

bool ZnccCorrelator::load(const std::uint16_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept {
  return load_impl(pixels, w, h, stride);
}
bool ZnccCorrelator::load(const std::int32_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept {
  return load_impl(pixels, w, h, stride);
}

template <typename T>
bool ZnccCorrelator::load_impl(const T* px, int w, int h, std::ptrdiff_t stride) noexcept {
  const int n = mask_.size_px();
  w = std::clamp(w, 0, fft_w_);
  h = std::clamp(h, 0, fft_h_);
  w_ = w;
  h_ = h;
  valid_w_ = std::max(0, w - n + 1);
  valid_h_ = std::max(0, h - n + 1);
  if (valid_w_ == 0 || valid_h_ == 0) return false;

  // Exact integer summed-area tables (no cancellation in Σf² − (Σf)²/n, flat is exactly 0).
  const std::size_t sw = static_cast<std::size_t>(w) + 1;
  std::int64_t* s1 = sat1_.data();
  std::int64_t* s2 = sat2_.data();
  for (std::size_t x = 0; x < sw; ++x) s1[x] = s2[x] = 0;
  for (int y = 0; y < h; ++y) {
    const T* row = px + y * stride;
    std::int64_t r1 = 0, r2 = 0;
    std::int64_t* a1 = s1 + (y + 1) * sw;
    std::int64_t* a2 = s2 + (y + 1) * sw;
    const std::int64_t* b1 = s1 + y * sw;
    const std::int64_t* b2 = s2 + y * sw;
    a1[0] = a2[0] = 0;
    for (int x = 0; x < w; ++x) {
      const std::int64_t v = row[x];
      r1 += v;
      r2 += v * v;
      a1[x + 1] = r1;
      a2[x + 1] = r2;
    }
    add_rows(a1 + 1, b1 + 1, a2 + 1, b2 + 1, w);
  }
  const std::int64_t total1 = s1[h * sw + w];
  const std::int64_t total2 = s2[h * sw + w];
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

void ZnccCorrelator::correlate(const Complex* spectrum, float* out) noexcept {
  multiply_spectra(reinterpret_cast<const float*>(image_spec_), reinterpret_cast<const float*>(spectrum),
                   reinterpret_cast<float*>(product_), spectrum_len());
  fftwf_execute_dft_c2r(static_cast<fftwf_plan>(plan_inverse_), reinterpret_cast<fftwf_complex*>(product_), corr_);
  for (int uy = 0; uy < valid_h_; ++uy) {
    const float* c = corr_ + static_cast<std::size_t>(uy) * fft_w_;
    const float* inv = inv_sigma_.data() + static_cast<std::size_t>(uy) * valid_w_;
    scale_clamp(c, inv, out + static_cast<std::size_t>(uy) * valid_w_, valid_w_);
  }
}

float ZnccCorrelator::score_at(const float* pattern, int ux, int uy) const noexcept {
  if (ux < 0 || uy < 0 || ux >= valid_w_ || uy >= valid_h_) return 0.0f;
  const float inv = inv_sigma_[static_cast<std::size_t>(uy) * valid_w_ + ux];
  if (inv == 0.0f) return 0.0f;
  const int n = mask_.size_px();
  float acc = 0.0f;
  for (const MaskBand& b : mask_.bands()) {
    for (int y = b.y0; y <= b.y1; ++y) {
      const float* t = pattern + y * n;
      const float* f = image_ + static_cast<std::size_t>(uy + y) * fft_w_ + ux;
      acc += dot(t + b.x0, f + b.x0, b.x1 - b.x0 + 1);
    }
  }
  return std::clamp(acc * inv, -1.0f, 1.0f);
}

}  // namespace sempose::pose
