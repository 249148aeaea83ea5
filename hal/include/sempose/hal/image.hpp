// A plain grey-level image (patterns, recorded full-field frames). Setup-time type: it owns
// a std::vector, so it is built before the loop and only read inside it.
#pragma once

#include <cstdint>
#include <vector>

namespace sempose::hal {

struct Image {
  std::int32_t width = 0;
  std::int32_t height = 0;
  std::uint8_t bits = 8;              // 8 or 16 significant bits (PGM maxval 255 or 65535)
  std::vector<std::uint16_t> pixels;  // row-major, width * height

  std::uint16_t at(std::int32_t x, std::int32_t y) const noexcept {
    return pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)];
  }
  bool empty() const noexcept { return width <= 0 || height <= 0; }
};

}  // namespace sempose::hal
