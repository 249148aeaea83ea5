#include "sempose/pose/window_noise.hpp"

#include "sempose/pose/simd_clones.hpp"

namespace sempose::pose {

namespace {
// One row of the window: Σ|D1| and Σ|D2| of the vertical second difference u of rows r0, r1, r2.
// Each u is recomputed from the three rows rather than carried along x, so the loop has no
// dependence between iterations and vectorises (AVX-512: ~2× faster than the carried form).
// |D2| ≤ 16·65535 and a row has ≤ 510 of them: the 32-bit sums cannot overflow.
SEMPOSE_CLONES void row_abs_differences(const std::uint16_t* r0, const std::uint16_t* r1, const std::uint16_t* r2, int p,
                                        std::int32_t& sum_d1, std::int32_t& sum_d2) noexcept {
  std::int32_t s1 = 0, s2 = 0;
  for (int x = 1; x + 1 < p; ++x) {
    const std::int32_t u_prev = r0[x - 1] - 2 * r1[x - 1] + r2[x - 1];
    const std::int32_t u = r0[x] - 2 * r1[x] + r2[x];
    const std::int32_t u_next = r0[x + 1] - 2 * r1[x + 1] + r2[x + 1];
    const std::int32_t d1 = u_next - u;
    const std::int32_t d2 = u_next - 2 * u + u_prev;
    s1 += d1 < 0 ? -d1 : d1;
    s2 += d2 < 0 ? -d2 : d2;
  }
  sum_d1 = s1;
  sum_d2 = s2;
}
}  // namespace

WindowNoise line_correlated_noise(const std::uint16_t* px, std::ptrdiff_t stride, int x0, int y0, int p) noexcept {
  WindowNoise out;
  if (p < 4 || p > 512) return out;
  std::int64_t abs_d1 = 0, abs_d2 = 0;
  for (int y = 1; y + 1 < p; ++y) {
    const std::uint16_t* r0 = px + static_cast<std::ptrdiff_t>(y0 + y - 1) * stride + x0;
    std::int32_t s1 = 0, s2 = 0;
    row_abs_differences(r0, r0 + stride, r0 + 2 * stride, p, s1, s2);
    abs_d1 += s1;
    abs_d2 += s2;
  }
  if (abs_d1 <= 0) return out;
  const double n = static_cast<double>(p - 2) * (p - 2);
  const double mean_abs_d2 = static_cast<double>(abs_d2) / n;
  const double ratio = static_cast<double>(abs_d2) / static_cast<double>(abs_d1);  // sd D2 / sd D1 = √(3 − ρ)
  double rho = 3.0 - ratio * ratio;
  rho = rho < 0.0 ? 0.0 : rho > WindowNoise::kMaxRho ? WindowNoise::kMaxRho : rho;
  out.rho = rho;
  out.var = M_PI / 2.0 * mean_abs_d2 * mean_abs_d2 / (12.0 * (1.0 - rho) * (3.0 - rho));  // Var D2 = (π/2)(E|D2|)²
  return out;
}

}  // namespace sempose::pose
