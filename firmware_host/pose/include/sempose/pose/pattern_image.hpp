// A grey-level image as the pose engine takes it at setup (a pattern, a shape mask): the pose
// engine's own type, so it does not depend on the hardware layer.
#pragma once

#include <cstdint>
#include <vector>

namespace sempose::pose {

struct PatternImage {
  std::int32_t width = 0;
  std::int32_t height = 0;
  std::vector<std::uint16_t> pixels;  // row-major, width * height
  bool empty() const noexcept { return width <= 0 || height <= 0; }
};

}  // namespace sempose::pose
