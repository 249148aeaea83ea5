#include "sempose/pose/bicubic_rotate.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

namespace {
// Keys cubic convolution kernel, a = −0.5.
inline double keys(double t) noexcept {
  t = std::fabs(t);
  if (t < 1) return (1.5 * t - 2.5) * t * t + 1;
  if (t < 2) return ((-0.5 * t + 2.5) * t - 4) * t + 2;
  return 0;
}
}  // namespace

void rotate_pattern(const float* src, int n, double phi_deg, float* out) noexcept {
  const double c = (n - 1) / 2.0;
  const double rad = phi_deg * M_PI / 180.0;
  const double cs = std::cos(rad), sn = std::sin(rad);
  auto at = [&](int x, int y) {
    x = std::clamp(x, 0, n - 1);
    y = std::clamp(y, 0, n - 1);
    return static_cast<double>(src[y * n + x]);
  };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      // Inverse map: output offset d comes from source offset R(−φ)·d. A CCW screen rotation
      // by φ maps (dx, dy) to (dx cos + dy sin, −dx sin + dy cos) (y points down).
      const double dx = x - c, dy = y - c;
      const double sx = c + dx * cs - dy * sn;
      const double sy = c + dx * sn + dy * cs;
      const int ix = static_cast<int>(std::floor(sx)), iy = static_cast<int>(std::floor(sy));
      const double fx = sx - ix, fy = sy - iy;
      double acc = 0;
      for (int j = -1; j <= 2; ++j) {
        const double wy = keys(j - fy);
        double row = 0;
        for (int i = -1; i <= 2; ++i) row += keys(i - fx) * at(ix + i, iy + j);
        acc += wy * row;
      }
      out[y * n + x] = static_cast<float>(acc);
    }
  }
}

}  // namespace sempose::pose
