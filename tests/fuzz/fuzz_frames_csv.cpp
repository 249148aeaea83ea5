// libFuzzer target: the replay `frames.csv` reader. The first byte picks the number of PGM
// frames (0..255), the rest is the file's text. Any text gives one t_ns per frame or a named
// error (std::runtime_error), never a crash, an overflow or an out-of-range index; accepted
// time stamps increase with the frame index.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "sempose/hal/frames_csv.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::size_t frames = data[0];
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    const auto t = sempose::hal::parse_frames_csv(text, frames, "frames.csv");
    if (t.size() != frames) std::abort();
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (t[i] < 0 || t[i] >= (std::int64_t{1} << 62)) std::abort();
      if (i > 0 && t[i] <= t[i - 1]) std::abort();
    }
  } catch (const std::runtime_error& e) {
    if (std::string(e.what()).rfind("frames.csv", 0) != 0) std::abort();  // names the file
  }
  return 0;
}
