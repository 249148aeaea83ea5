// libFuzzer target: the PGM reader (every pattern, mask, texture and replay frame goes
// through it). Any input must give an image that matches its header or a named error.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "sempose/hal/pgm.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<unsigned char> bytes(data, data + size);
  sempose::hal::Image img;
  std::string error;
  if (sempose::hal::parse_pgm(bytes, img, error)) {
    // Accepted: the header's promise holds (a lie here would be read past by the tracker).
    const bool sane = img.width >= 1 && img.height >= 1 && img.width <= sempose::hal::kPgmMaxSide &&
                      img.height <= sempose::hal::kPgmMaxSide && (img.bits == 8 || img.bits == 16) &&
                      img.pixels.size() == static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height) &&
                      error.empty();
    if (!sane) std::abort();
  } else if (error.empty()) {
    std::abort();  // a refusal must say why
  }
  return 0;
}
