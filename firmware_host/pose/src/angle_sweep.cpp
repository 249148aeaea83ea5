#include "sempose/pose/angle_sweep.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

Measurement AngleSweep::sweep(const PatternBank& bank, int j_centre, double window_deg, double step_deg,
                              int max_moves, const SearchWindow& win) noexcept {
  const int stride = std::max(1, static_cast<int>(std::lround(step_deg / angles_.step_deg)));
  const int half_count = static_cast<int>(std::floor(window_deg / angles_.step_deg / stride + 1e-9));
  Peak best;
  best.score = -3.0f;
  int best_j = j_centre;
  int ffts = 0;
  for (int i = -half_count; i <= half_count; ++i) {
    const int j = angles_.wrap(j_centre + i * stride);
    half_.correlate(bank.spectrum(j), maps_.work());
    ++ffts;
    const Peak pk = find_peak(maps_.work(), half_.valid_w(), half_.valid_h(), win);
    if (pk.score > best.score) {
      best = pk;
      best_j = j;
      maps_.keep_work_as_best();
    }
  }
  Measurement m = walk_.measure(bank, best_j, best, max_moves);
  m.steps += ffts;
  return m;
}

}  // namespace sempose::pose
