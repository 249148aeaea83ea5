#include "sempose/pose/attainable_score.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/simd_clones.hpp"

namespace sempose::pose {

namespace {
// Σv and Σv² of one row (p ≤ 512: the 64-bit sums are exact).
SEMPOSE_CLONES void row_moments(const std::uint16_t* row, int p, std::int64_t& sum, std::int64_t& sum2) noexcept {
  std::int64_t s = 0, s2 = 0;
  for (int x = 0; x < p; ++x) {
    const std::int64_t v = row[x];
    s += v;
    s2 += v * v;
  }
  sum += s;
  sum2 += s2;
}
}  // namespace

AttainableScore attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy, int p,
                                 const PrefilterNoiseGain& gain) noexcept {
  const MaskBand whole{0, p - 1, 0, p - 1};
  return attainable_score(px, w, h, cx, cy, p, &whole, 1, gain);
}

AttainableScore attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy, int p,
                                 const MaskBand* bands, int n_bands, const PrefilterNoiseGain& gain) noexcept {
  AttainableScore a;
  if (px == nullptr || w < p || h < p || p < 4) return a;
  const int x0 = std::clamp(static_cast<int>(std::lround(cx - (p - 1) / 2.0)), 0, w - p);
  const int y0 = std::clamp(static_cast<int>(std::lround(cy - (p - 1) / 2.0)), 0, h - p);
  std::int64_t sum = 0, sum2 = 0;  // exact: p² · 65535² < 2^63 for any pattern side that fits a frame
  std::int64_t count = 0;
  for (int b = 0; b < n_bands; ++b) {
    const MaskBand& band = bands[b];
    const int bw = band.x1 - band.x0 + 1;
    for (int y = band.y0; y <= band.y1; ++y)
      row_moments(px + static_cast<std::size_t>(y0 + y) * w + x0 + band.x0, bw, sum, sum2);
    count += static_cast<std::int64_t>(bw) * (band.y1 - band.y0 + 1);
  }
  if (count < 2) return a;
  const double n = static_cast<double>(count);
  const double mean = static_cast<double>(sum) / n;
  a.window_var = std::max(0.0, static_cast<double>(sum2) / n - mean * mean);
  a.noise = line_correlated_noise(px, w, x0, y0, p);
  const double noise = std::min(a.window_var, a.noise.var);
  const double signal = a.window_var - noise;
  const double left = signal + gain.line_correlated(a.noise.rho) * noise;
  a.score = left > 0 ? std::sqrt(signal / left) : 0.0;
  return a;
}

double pattern_attainable_factor(const std::uint16_t* px, int n, const WindowNoise& noise,
                                 const PrefilterNoiseGain& gain) noexcept {
  if (px == nullptr || n < 4 || !(noise.var > 0)) return 1.0;
  std::int64_t sum = 0, sum2 = 0;
  for (int y = 0; y < n; ++y) row_moments(px + static_cast<std::size_t>(y) * n, n, sum, sum2);
  const double count = static_cast<double>(n) * n;
  const double mean = static_cast<double>(sum) / count;
  const double var = std::max(0.0, static_cast<double>(sum2) / count - mean * mean);
  const double nv = std::min(var, noise.var);
  const double signal = var - nv;
  const double left = signal + gain.line_correlated(noise.rho) * nv;
  return left > 0 ? std::sqrt(signal / left) : 1.0;
}

}  // namespace sempose::pose
