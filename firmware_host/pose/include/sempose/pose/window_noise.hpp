// The detector noise in a square window of raw pixels, by Immerkær's estimator: the
// Laplacian-difference kernel cancels linear structure (edges, gradients), so what is left
// is noise: σ = √(π/2)·Σ|I∗L| / (6·rows·(p−2)). The tracker's attainable score reads every
// row; the appearance observer one row in eight (first_row, row_step). RT: one pass, integer
// arithmetic (exact, so the sum does not depend on the order), no allocation.
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

}  // namespace sempose::pose
