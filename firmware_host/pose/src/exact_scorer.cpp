#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/simd_clones.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

namespace {

constexpr int kChunkPx = 16;

// Σ t·f over bands of the pattern: pattern t (size×size), image f at the window's top-left
// (row stride). The hot loop of every exact evaluation, cloned for AVX-512 / AVX2 (the build
// targets baseline x86-64). The bands are the circle's, widened to whole 16-float chunks: t
// is zero outside its support, so the extra products add exactly nothing, and each chunk is
// one vector multiply-add into 16 lane sums reduced once at the end (a per-row horizontal
// reduction cost more than the products themselves).
SEMPOSE_CLONES double masked_dot(const float* t, int size,
                                                                           const float* f, std::ptrdiff_t stride,
                                                                           const MaskBand* bands,
                                                                           int n_bands) noexcept {
  float lanes[kChunkPx] = {};
  float tail = 0;
  for (int k = 0; k < n_bands; ++k) {
    const MaskBand& b = bands[k];
    const int n = b.x1 - b.x0 + 1, n_vec = n / kChunkPx * kChunkPx;
    for (int y = b.y0; y <= b.y1; ++y) {
      const float* tr = t + static_cast<std::ptrdiff_t>(y) * size + b.x0;
      const float* fr = f + static_cast<std::ptrdiff_t>(y) * stride + b.x0;
      for (int x = 0; x < n_vec; x += kChunkPx) {
#pragma omp simd
        for (int l = 0; l < kChunkPx; ++l) lanes[l] += tr[x + l] * fr[x + l];
      }
      for (int x = n_vec; x < n; ++x) tail += tr[x] * fr[x];
    }
  }
  double total = tail;
  for (float v : lanes) total += v;
  return total;
}

// Σ x·f and Σ y·f over support bands (x, y in pixels from the pattern's centre c): the
// background plane's products, for the sub-pixel fit only.
SEMPOSE_CLONES void plane_moments(const float* f, std::ptrdiff_t stride, const MaskBand* bands, int n_bands, float c,
                                  double& xf, double& yf) noexcept {
  double sx = 0, sy = 0;
  for (int k = 0; k < n_bands; ++k) {
    const MaskBand& b = bands[k];
    for (int y = b.y0; y <= b.y1; ++y) {
      const float* fr = f + static_cast<std::ptrdiff_t>(y) * stride;
      float rx = 0, r = 0;
#pragma omp simd reduction(+ : rx, r)
      for (int x = b.x0; x <= b.x1; ++x) {
        rx += (static_cast<float>(x) - c) * fr[x];
        r += fr[x];
      }
      sx += rx;
      sy += (static_cast<double>(y) - c) * r;
    }
  }
  xf = sx;
  yf = sy;
}

// Σ v over n integers, in independent lanes (vectorised; exact, so any order gives the same).
SEMPOSE_CLONES std::int64_t integer_sum(const std::int32_t* v, std::size_t n) noexcept {
  std::int64_t lanes[kChunkPx] = {};
  std::size_t i = 0;
  for (; i + kChunkPx <= n; i += kChunkPx) {
#pragma omp simd
    for (int l = 0; l < kChunkPx; ++l) lanes[l] += v[i + l];
  }
  std::int64_t total = 0;
  for (; i < n; ++i) total += v[i];
  for (std::int64_t l : lanes) total += l;
  return total;
}

}  // namespace

ExactScorer::ExactScorer(const PatternMask& fine_mask, int max_roi_px)
    : pattern_px_(fine_mask.size_px()),
      max_roi_px_(max_roi_px),
      chunk_bands_(widen_to_chunks(fine_mask, kChunkPx)),
      roi_(static_cast<std::size_t>(max_roi_px) * max_roi_px, 0.0f),
      tables_(max_roi_px, max_roi_px) {}

void ExactScorer::load(const std::int32_t* filtered, int w, int h) noexcept {
  // Tabled on demand: parts() covers the windows it reads (about half of a 192² ROI).
  tables_.attach(filtered, w, h, w);
  roi_w_ = std::clamp(w, 0, max_roi_px_);
  roi_h_ = std::clamp(h, 0, max_roi_px_);
  // The ROI's mean, exact (integer sum; a running double sum is a serial chain of dependent adds).
  const std::size_t n = static_cast<std::size_t>(roi_w_) * roi_h_;
  const float mean = static_cast<float>(static_cast<double>(integer_sum(filtered, n)) / static_cast<double>(n));
  roi_mean_ = mean;
  for (std::size_t i = 0; i < n; ++i) roi_[i] = static_cast<float>(filtered[i]) - mean;
}

ScoreParts ExactScorer::parts(const PatternBank& bank, int j, int ux, int uy) const noexcept {
  ScoreParts p;
  if (ux < 0 || uy < 0 || ux > roi_w_ - pattern_px_ || uy > roi_h_ - pattern_px_) return p;
  // The window's sums over this angle's support (the circle, or the turned shape mask).
  std::int64_t s1 = 0, s2 = 0;
  const MaskBand* bands = bank.support_bands(j);
  const int n_bands = bank.support_band_count(j);
  tables_.cover(ux, uy, ux + pattern_px_ - 1, uy + pattern_px_ - 1);
  for (int k = 0; k < n_bands; ++k) {
    const MaskBand& b = bands[k];
    tables_.add_rect(ux + b.x0, uy + b.y0, ux + b.x1, uy + b.y1, s1, s2);
  }
  // The pattern is zero outside its support, so the dot product may run over the whole
  // (chunk-widened) circle. Σt = 0 under the support, so Σ t·(f − mean) = Σ t·f for any
  // offset of f.
  p.tf = masked_dot(bank.pattern(j), pattern_px_, roi_.data() + static_cast<std::size_t>(uy) * roi_w_ + ux, roi_w_,
                    chunk_bands_.data(), static_cast<int>(chunk_bands_.size()));
  p.count = static_cast<double>(bank.support_count(j));
  p.var = static_cast<double>(s2) - static_cast<double>(s1) * static_cast<double>(s1) / p.count;
  p.sum = static_cast<double>(s1);
  p.inside = true;
  return p;
}

PlaneParts ExactScorer::plane_parts(const PatternBank& bank, int j, int ux, int uy, const ScoreParts& p) const noexcept {
  // The tables summed the ROI before its mean was taken off.
  return p.inside ? plane_parts_given_sum(bank, j, ux, uy, p.sum - p.count * roi_mean_) : PlaneParts{};
}

PlaneParts ExactScorer::plane_parts_given_sum(const PatternBank& bank, int j, int ux, int uy, double sum_f) const noexcept {
  PlaneParts out;
  if (ux < 0 || uy < 0 || ux > roi_w_ - pattern_px_ || uy > roi_h_ - pattern_px_) return out;
  double xf = 0, yf = 0;
  plane_moments(roi_.data() + static_cast<std::size_t>(uy) * roi_w_ + ux, roi_w_, bank.support_bands(j),
                bank.support_band_count(j), static_cast<float>((pattern_px_ - 1) / 2.0), xf, yf);
  // The dots ran on the mean-free ROI: the regressors centred by their means times its sum.
  const PatternBank::PlaneGram& g = bank.plane_gram(j);
  out.xf = xf / pattern_px_ - g.mean_x * sum_f;
  out.yf = yf / pattern_px_ - g.mean_y * sum_f;
  out.inside = true;
  return out;
}

void ExactScorer::plane_parts_3x3(const PatternBank& bank, int j, int ux, int uy, PlaneParts* out) const noexcept {
  for (int k = 0; k < 9; ++k) out[k] = PlaneParts{};
  if (ux < 1 || uy < 1 || ux + 1 > roi_w_ - pattern_px_ || uy + 1 > roi_h_ - pattern_px_) return;
  const double c = (pattern_px_ - 1) / 2.0;
  double m0[9] = {}, mx[9] = {}, my[9] = {};  // Σ f, Σ (x − c)·f, Σ (y − c)·f per place
  const MaskBand* bands = bank.support_bands(j);
  for (int b = 0; b < bank.support_band_count(j); ++b) {
    const MaskBand& band = bands[b];
    const int x0 = band.x0, x1 = band.x1;
    for (int y = band.y0; y <= band.y1; ++y) {
      for (int oy = -1; oy <= 1; ++oy) {
        const float* fr = roi_.data() + static_cast<std::size_t>(uy + oy + y) * roi_w_ + ux;
        float s0 = 0, s1 = 0;
#pragma omp simd reduction(+ : s0, s1)
        for (int x = x0; x <= x1; ++x) {
          s0 += fr[x];
          s1 += static_cast<float>(x) * fr[x];
        }
        // Place ox reads columns x0 + ox … x1 + ox of this row as the window's x0 … x1.
        const double lo = fr[x0 - 1], hi = fr[x1 + 1], first = fr[x0], last = fr[x1];
        const double a0[3] = {s0 + lo - last, s0, s0 + hi - first};
        const double a1[3] = {s1 + (x0 - 1) * lo - x1 * last, s1, s1 + (x1 + 1) * hi - x0 * first};
        for (int ox = -1; ox <= 1; ++ox) {
          const int k = (ox + 1) + 3 * (oy + 1);
          m0[k] += a0[ox + 1];
          mx[k] += a1[ox + 1] - (ox + c) * a0[ox + 1];
          my[k] += (y - c) * a0[ox + 1];
        }
      }
    }
  }
  const PatternBank::PlaneGram& g = bank.plane_gram(j);
  for (int k = 0; k < 9; ++k) {
    out[k].xf = mx[k] / pattern_px_ - g.mean_x * m0[k];
    out[k].yf = my[k] / pattern_px_ - g.mean_y * m0[k];
    out[k].inside = true;
  }
}

float ExactScorer::zncc(const ScoreParts& p) noexcept {
  if (!(p.var > 0.25 * p.count)) return 0.0f;
  return static_cast<float>(std::clamp(p.tf / std::sqrt(p.var), -1.0, 1.0));
}

float ExactScorer::score(const PatternBank& bank, int j, int ux, int uy) const noexcept {
  const ScoreParts p = parts(bank, j, ux, uy);
  return p.inside ? zncc(p) : -2.0f;
}

std::size_t ExactScorer::memory_bytes() const noexcept { return roi_.size() * sizeof(float) + tables_.memory_bytes(); }

}  // namespace sempose::pose
