#include "sempose/pose/peak_finder.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdlib>

namespace sempose::pose {

Peak find_peak(const float* map, int vw, int vh, const SearchWindow& win) noexcept {
  Peak p;
  p.score = -2.0f;
  const int ya = std::max(0, win.y0), yb = std::min(vh - 1, win.y1);
  const int xa = std::max(0, win.x0), xb = std::min(vw - 1, win.x1);
  p.ux = std::clamp(xa, 0, vw - 1);
  p.uy = std::clamp(ya, 0, vh - 1);
  for (int y = ya; y <= yb; ++y) {
    const float* row = map + static_cast<std::size_t>(y) * vw;
    for (int x = xa; x <= xb; ++x) {
      if (row[x] > p.score) {
        p.score = row[x];
        p.ux = x;
        p.uy = y;
      }
    }
  }
  double sum = 0, sum2 = 0;
  int count = 0;
  for (int y = 0; y < vh; ++y) {
    const float* row = map + static_cast<std::size_t>(y) * vw;
    const bool near_y = std::abs(y - p.uy) <= 5;
    for (int x = 0; x < vw; ++x) {
      if (near_y && std::abs(x - p.ux) <= 5) continue;
      sum += row[x];
      sum2 += static_cast<double>(row[x]) * row[x];
      ++count;
    }
  }
  if (count >= 20) {
    const double mean = sum / count;
    const double var = std::max(0.0, sum2 / count - mean * mean);
    const double sd = std::sqrt(var);
    p.psr = sd > 1e-6 ? static_cast<float>(std::clamp((p.score - mean) / sd, -1000.0, 1000.0)) : 1000.0f;
    p.psr_valid = true;
  }
  return p;
}

}  // namespace sempose::pose
