#include "sempose/pose/pattern_rim.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "sempose/pose/prefilter.hpp"

namespace sempose::pose {

RimShare rim_information_share(const std::uint16_t* pixels, int n, int prefilter_passes) {
  RimShare r;
  if (pixels == nullptr || n < 8) return r;
  std::vector<float> p(static_cast<std::size_t>(n) * n);
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = static_cast<float>(pixels[i]);
  prefilter_pattern(p.data(), n, prefilter_passes);
  const double c = (n - 1) / 2.0, radius = n / 2.0 - 1.0, inner = radius * (1.0 - kRimFraction);
  double all_x = 0, all_y = 0, rim_x = 0, rim_y = 0;
  long pixels_in = 0, pixels_rim = 0;
  for (int y = 1; y < n - 1; ++y) {
    for (int x = 1; x < n - 1; ++x) {
      const double d = std::hypot(x - c, y - c);
      if (d > radius) continue;
      const std::size_t k = static_cast<std::size_t>(y) * n + x;
      const double gx = 0.5 * (p[k + 1] - p[k - 1]), gy = 0.5 * (p[k + n] - p[k - n]);
      all_x += gx * gx;
      all_y += gy * gy;
      ++pixels_in;
      if (d > inner) {
        rim_x += gx * gx;
        rim_y += gy * gy;
        ++pixels_rim;
      }
    }
  }
  if (!(all_x > 0) || !(all_y > 0) || pixels_in == 0) return r;
  r.x = rim_x / all_x;
  r.y = rim_y / all_y;
  r.area = static_cast<double>(pixels_rim) / static_cast<double>(pixels_in);
  r.ring_px = std::max(1, static_cast<int>(std::lround(radius * kRimFraction)));
  r.valid = true;
  return r;
}

std::string rim_warning(const RimShare& r) {
  if (!r.valid || std::max(r.x, r.y) < kRimShareWarn) return "";
  const bool along_x = r.x >= r.y;
  char b[512];
  std::snprintf(b, sizeof b,
                "%.0f %% of its position information along %s lies in its outer %d px (%.0f %% of its area): a target "
                "reaching the pattern's rim is placed by the background recorded beyond it, which differs wherever "
                "the target moves and pulls the pose several px along %s, unseen; record a larger pattern around the "
                "target or give a shape mask (targets[].pattern_sets[].mask)",
                100.0 * (along_x ? r.x : r.y), along_x ? "x" : "y", r.ring_px, 100.0 * r.area, along_x ? "x" : "y");
  return b;
}

}  // namespace sempose::pose
