// The bank's angle steps: index j ↔ angle j·step_deg, indices wrapping around the circle.
#pragma once

#include <cmath>

namespace sempose::pose {

struct AngleGrid {
  int count = 360;
  double step_deg = 1.0;

  int wrap(int j) const noexcept {
    j %= count;
    return j < 0 ? j + count : j;
  }
  // The nearest step to an angle in degrees.
  int index_of(double deg) const noexcept { return wrap(static_cast<int>(std::lround(deg / step_deg))); }
};

}  // namespace sempose::pose
