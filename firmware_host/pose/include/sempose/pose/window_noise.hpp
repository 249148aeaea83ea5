// The detector noise in a square window of raw pixels. window_noise_var: Immerkær's estimator: the
// Laplacian-difference kernel cancels linear structure (edges, gradients), so what is left
// is noise: σ = √(π/2)·Σ|I∗L| / (6·rows·(p−2)); the appearance observer reads one row in eight
// (first_row, row_step). RT: one pass, integer
// arithmetic (exact, so the sum does not depend on the order), no allocation. It assumes white
// noise; line_correlated_noise (below) also reads the detector's low-pass along the line.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace sempose::pose {

// Variance of the noise in the p×p window at (x0, y0) of px (row stride `stride`), from the
// Laplacian at rows first_row, first_row + row_step, … < p − 1. 0 when no row qualifies.
inline double window_noise_var(const std::uint16_t* px, std::ptrdiff_t stride, int x0, int y0, int p, int first_row = 1,
                               int row_step = 1) noexcept {
  std::int64_t abs_lap = 0;
  int rows = 0;
  for (int y = first_row; y + 1 < p; y += row_step) {
    ++rows;
    const std::uint16_t* r0 = px + static_cast<std::ptrdiff_t>(y0 + y - 1) * stride + x0;
    const std::uint16_t* r1 = r0 + stride;
    const std::uint16_t* r2 = r1 + stride;
    std::int64_t row_sum = 0;
    for (int x = 1; x + 1 < p; ++x) {
      const std::int32_t l = (r0[x - 1] - 2 * r0[x] + r0[x + 1]) - 2 * (r1[x - 1] - 2 * r1[x] + r1[x + 1]) +
                             (r2[x - 1] - 2 * r2[x] + r2[x + 1]);  // |l| ≤ 16·65535
      row_sum += l < 0 ? -l : l;
    }
    abs_lap += row_sum;
  }
  if (rows == 0) return 0.0;
  const double sigma = std::sqrt(M_PI / 2.0) * static_cast<double>(abs_lap) / (6.0 * rows * (p - 2));
  return sigma * sigma;
}

// The detector noise of a window when it may be correlated along the scan line. An SEM's
// detector is a first-order low-pass in time, so along a line each pixel keeps a share ρ of
// the previous one (ρ = exp(−dwell/τ), ~0.1–0.4 at short dwell) while pixels of different
// lines, scanned a whole line period apart, stay independent. Immerkær's kernel is the
// horizontal second difference of the vertical second difference u; under that correlation
// its variance is 12σ²(1−ρ)(3−ρ) instead of 36σ², so it reads too little noise, and the
// prefilter keeps more of correlated noise than of white noise (Σ k_i k_j ρ^|i−j| along x).
// Both the horizontal first (D1) and second (D2) difference of u cancel what is constant
// along a line in u (a horizontal edge) and u is 0 on a vertical edge, so both see noise;
// their ratio gives ρ: Var D2 / Var D1 = 3 − ρ (AR(1)), and D2 then gives σ². Mean squares,
// not Immerkær's mean absolute values: E|X| = σ√(2/π) holds for Gaussian noise only, and at
// 1–2.5 e⁻/px the Poisson × Gamma cascade is skewed enough that it read 20 % too little noise
// (pose_attainable_score_test); squares are exact for any distribution, at the price of a few
// per cent of edge signal counted as noise.
struct WindowNoise {
  double var = 0;  // variance of one raw pixel's noise (as the detector delivers it, correlation included)
  double rho = 0;  // its correlation with the previous pixel of the same line, in [0, kMaxRho]
  static constexpr double kMaxRho = 0.9;  // τ ≈ 9.5 px: beyond, the line is a smear and ρ is not measurable
};

// RT: one pass over the p×p window at (x0, y0) of px (row stride `stride`), integer sums per
// row (exact), no allocation. p ≥ 4.
inline WindowNoise line_correlated_noise(const std::uint16_t* px, std::ptrdiff_t stride, int x0, int y0, int p) noexcept {
  WindowNoise out;
  if (p < 4) return out;
  double sq_d1 = 0, sq_d2 = 0;
  for (int y = 1; y + 1 < p; ++y) {
    const std::uint16_t* r0 = px + static_cast<std::ptrdiff_t>(y0 + y - 1) * stride + x0;
    const std::uint16_t* r1 = r0 + stride;
    const std::uint16_t* r2 = r1 + stride;
    std::int64_t s1 = 0, s2 = 0;  // d² ≤ (16·65535)² < 2^40: a row of up to 2^23 px stays exact
    std::int32_t u_prev = r0[0] - 2 * r1[0] + r2[0];
    std::int32_t u = r0[1] - 2 * r1[1] + r2[1];
    for (int x = 1; x + 1 < p; ++x) {
      const std::int32_t u_next = r0[x + 1] - 2 * r1[x + 1] + r2[x + 1];  // |u| ≤ 4·65535
      const std::int32_t d1 = u_next - u;
      const std::int32_t d2 = u_next - 2 * u + u_prev;
      s1 += static_cast<std::int64_t>(d1) * d1;
      s2 += static_cast<std::int64_t>(d2) * d2;
      u_prev = u;
      u = u_next;
    }
    sq_d1 += static_cast<double>(s1);
    sq_d2 += static_cast<double>(s2);
  }
  if (sq_d1 <= 0) return out;
  const double n = static_cast<double>(p - 2) * (p - 2);
  const double var_d2 = sq_d2 / n;  // E D2²
  const double ratio = sq_d2 / sq_d1;
  double rho = 3.0 - ratio;
  rho = rho < 0.0 ? 0.0 : rho > WindowNoise::kMaxRho ? WindowNoise::kMaxRho : rho;
  out.rho = rho;
  out.var = var_d2 / (12.0 * (1.0 - rho) * (3.0 - rho));
  return out;
}

}  // namespace sempose::pose
