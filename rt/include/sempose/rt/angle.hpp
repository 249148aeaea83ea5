// Angles in degrees wrapped to (-180, 180] (the pose convention): the one wrap the tracker,
// the pose filter and the simulator's trajectories share. Exact: fmod is exact and the ±360
// correction subtracts numbers within a factor of two of each other (Sterbenz), so no
// rounding enters.
#pragma once

#include <cmath>

namespace sempose::rt {

inline double wrap_deg(double deg) noexcept {
  double r = std::fmod(deg, 360.0);
  if (r <= -180.0) r += 360.0;
  if (r > 180.0) r -= 360.0;
  return r;
}

}  // namespace sempose::rt
