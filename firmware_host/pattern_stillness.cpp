#include "pattern_stillness.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/window_noise.hpp"

namespace sempose::cli {

double scan_noise_var(const hal::Image& frame, int x0, int y0, int size) {
  return pose::line_correlated_noise(frame.pixels.data(), frame.width, x0, y0, size).var;
}

StillnessCheck check_stillness(const std::vector<double>& mean_window, std::size_t frames, double scan_noise_var_,
                               const hal::Image& frame, int x0, int y0, int size) {
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  for (int y = 0; y < size; ++y) {
    const double* ra = mean_window.data() + static_cast<std::size_t>(y) * size;
    const std::uint16_t* rb = frame.pixels.data() + static_cast<std::size_t>(y0 + y) * frame.width + x0;
    for (int x = 0; x < size; ++x) {
      const double va = ra[x], vb = rb[x];
      sa += va;
      sb += vb;
      saa += va * va;
      sbb += vb * vb;
      sab += va * vb;
    }
  }
  const double n = static_cast<double>(size) * size;
  const double cov = sab - sa * sb / n, va = saa - sa * sa / n, vb = sbb - sb * sb / n;
  StillnessCheck c;
  c.zncc = va > 0 && vb > 0 ? cov / std::sqrt(va * vb) : 0.0;
  const double noise = std::max(scan_noise_var_, scan_noise_var(frame, x0, y0, size));
  const double s = std::max(0.0, vb / n - noise);
  const double m = static_cast<double>(std::max<std::size_t>(frames, 1));
  c.expected = s > 0 ? std::sqrt(s / (s + noise / m)) * std::sqrt(s / (s + noise)) : 0.0;
  const double se = (1.0 - c.expected * c.expected) / std::sqrt(0.5 * n);
  c.lowest = c.expected - kNoiseBiasShare * (1.0 - c.expected) - kStandardErrors * se;
  c.still = c.zncc >= c.lowest;
  return c;
}

}  // namespace sempose::cli
