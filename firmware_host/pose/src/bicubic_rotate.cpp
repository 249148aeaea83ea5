#include "sempose/pose/bicubic_rotate.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace sempose::pose {

namespace {
// Keys cubic convolution kernel, a = −0.5.
inline double keys(double t) noexcept {
  t = std::fabs(t);
  if (t < 1) return (1.5 * t - 2.5) * t * t + 1;
  if (t < 2) return ((-0.5 * t + 2.5) * t - 4) * t + 2;
  return 0;
}

// Bicubic sample of a w×w grid at (sx, sy), clamped to its border.
inline double keys_at(const float* g, int w, double sx, double sy) noexcept {
  auto at = [&](int x, int y) {
    x = std::clamp(x, 0, w - 1);
    y = std::clamp(y, 0, w - 1);
    return static_cast<double>(g[static_cast<std::size_t>(y) * w + x]);
  };
  const int ix = static_cast<int>(std::floor(sx)), iy = static_cast<int>(std::floor(sy));
  const double fx = sx - ix, fy = sy - iy;
  double acc = 0;
  for (int j = -1; j <= 2; ++j) {
    const double wy = keys(j - fy);
    double row = 0;
    for (int i = -1; i <= 2; ++i) row += keys(i - fx) * at(ix + i, iy + j);
    acc += wy * row;
  }
  return acc;
}

// The periodic sinc (Dirichlet kernel) of an odd period L: interpolates L samples exactly
// band-limited (no Nyquist bin at odd L). t in samples.
inline double dirichlet(double t, int L) noexcept {
  const double r = std::round(t);
  if (std::fabs(t - r) < 1e-12) return std::fmod(std::fabs(r), static_cast<double>(L)) == 0 ? 1.0 : 0.0;
  return std::sin(M_PI * t) / (L * std::sin(M_PI * t / L));
}
}  // namespace

void rotate_pattern(const float* src, int n, double phi_deg, float* out) noexcept {
  const double c = (n - 1) / 2.0;
  const double rad = phi_deg * M_PI / 180.0;
  const double cs = std::cos(rad), sn = std::sin(rad);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      // Inverse map: output offset d comes from source offset R(−φ)·d. A CCW screen rotation
      // by φ maps (dx, dy) to (dx cos + dy sin, −dx sin + dy cos) (y points down).
      const double dx = x - c, dy = y - c;
      const double sx = c + dx * cs - dy * sn;
      const double sy = c + dx * sn + dy * cs;
      out[y * n + x] = static_cast<float>(keys_at(src, n, sx, sy));
    }
  }
}

PatternRotator::PatternRotator(const float* src, int n) : n_(n) {
  // A margin of a quarter of the size holds the rotated corners (at most (√2 − 1)/2 ≈ 0.21·n
  // outside); odd canvas length (the Dirichlet kernel's exact form).
  margin_ = std::max(8, (n + 3) / 4);
  len_ = n + 2 * margin_;
  if (len_ % 2 == 0) ++len_;
  up_len_ = kUp * len_;
  const int L = len_, m = margin_;
  double mean = 0;
  for (int i = 0; i < n * n; ++i) mean += src[i];
  mean /= static_cast<double>(n) * n;
  // Clamped for a quarter of the margin past the border, then a raised-cosine taper to the
  // mean at the canvas edge: continuous across the period, so the sinc does not ring there.
  const double keep = 0.25 * m, ramp = m - keep;
  auto taper = [&](int i) {
    const int d = i < 0 ? -i : i > n - 1 ? i - (n - 1) : 0;
    if (d <= keep) return 1.0;
    if (d >= m) return 0.0;
    return 0.5 * (1 + std::cos(M_PI * (d - keep) / ramp));
  };
  std::vector<double> canvas(static_cast<std::size_t>(L) * L);
  for (int Y = 0; Y < L; ++Y)
    for (int X = 0; X < L; ++X) {
      const int x = X - m, y = Y - m;
      const double v = src[static_cast<std::size_t>(std::clamp(y, 0, n - 1)) * n + std::clamp(x, 0, n - 1)];
      canvas[static_cast<std::size_t>(Y) * L + X] = mean + (v - mean) * taper(x) * taper(y);
    }
  // Separable band-limited interpolation: rows to the fine grid, then columns.
  const int U = up_len_;
  std::vector<double> kernel(static_cast<std::size_t>(U) * L);  // kernel[u·L + x] = D(u/kUp − x)
  for (int u = 0; u < U; ++u)
    for (int x = 0; x < L; ++x) kernel[static_cast<std::size_t>(u) * L + x] = dirichlet(static_cast<double>(u) / kUp - x, L);
  std::vector<double> rows(static_cast<std::size_t>(L) * U);  // rows[Y·U + u]
  for (int Y = 0; Y < L; ++Y) {
    const double* in = canvas.data() + static_cast<std::size_t>(Y) * L;
    for (int u = 0; u < U; ++u) {
      const double* k = kernel.data() + static_cast<std::size_t>(u) * L;
      double acc = 0;
      for (int x = 0; x < L; ++x) acc += k[x] * in[x];
      rows[static_cast<std::size_t>(Y) * U + u] = acc;
    }
  }
  up_.assign(static_cast<std::size_t>(U) * U, 0.0f);
  std::vector<double> acc(static_cast<std::size_t>(U));
  for (int v = 0; v < U; ++v) {
    const double* k = kernel.data() + static_cast<std::size_t>(v) * L;
    std::fill(acc.begin(), acc.end(), 0.0);
    for (int Y = 0; Y < L; ++Y) {
      const double w = k[Y];
      if (w == 0.0) continue;
      const double* r = rows.data() + static_cast<std::size_t>(Y) * U;
      for (int u = 0; u < U; ++u) acc[static_cast<std::size_t>(u)] += w * r[u];
    }
    float* o = up_.data() + static_cast<std::size_t>(v) * U;
    for (int u = 0; u < U; ++u) o[u] = static_cast<float>(acc[static_cast<std::size_t>(u)]);
  }
}

void PatternRotator::rotate(double phi_deg, float* out) const noexcept {
  const int n = n_;
  const double c = (n - 1) / 2.0;
  const double rad = phi_deg * M_PI / 180.0;
  const double cs = std::cos(rad), sn = std::sin(rad);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      // rotate_pattern's inverse map, on the fine grid (source pixel s at kUp·(s + margin)).
      const double dx = x - c, dy = y - c;
      const double sx = c + dx * cs - dy * sn;
      const double sy = c + dx * sn + dy * cs;
      out[static_cast<std::size_t>(y) * n + x] =
          static_cast<float>(keys_at(up_.data(), up_len_, kUp * (sx + margin_), kUp * (sy + margin_)));
    }
}

}  // namespace sempose::pose
