// The maximum of a ZNCC map inside a window, and its peak-to-sidelobe ratio (sidelobe = the
// whole map outside an 11×11 window around the peak). RT, no allocation.
#pragma once

namespace sempose::pose {

struct Peak {
  int ux = 0, uy = 0;
  float score = 0;
  float psr = 0;
  bool psr_valid = false;
};

// Inclusive search window in map coordinates (the default: the whole map).
struct SearchWindow {
  int x0 = 0, y0 = 0, x1 = 1 << 30, y1 = 1 << 30;
};

Peak find_peak(const float* map, int map_w, int map_h, const SearchWindow& window = {}) noexcept;

}  // namespace sempose::pose
