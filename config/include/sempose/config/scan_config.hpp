// What the scan generator can do: field size, ROI and dwell limits, line flyback, output
// bits. YAML section `scan:` (read_scan). hal::ScanLimits is an alias of this struct.
#pragma once

#include <cstdint>

namespace sempose::config {

class Section;

struct ScanLimits {
  std::int32_t field_w = 1024;  // full scan field, pixels
  std::int32_t field_h = 768;
  std::int32_t max_roi_w = 256;  // largest ROI besides the full field
  std::int32_t max_roi_h = 256;
  std::uint32_t min_dwell_ns = 100;
  std::uint32_t max_dwell_ns = 10'000;
  std::uint32_t dwell_step_ns = 50;  // requested dwells are rounded to a multiple of this
  std::uint32_t line_flyback_ns = 2'000;
  std::uint8_t bits = 8;  // 8 or 16 bits per pixel, like the frame grabber

  // w·h·dwell + h·flyback (README: The simulated SEM).
  std::int64_t scan_time_ns(std::int32_t w, std::int32_t h, std::uint32_t dwell_ns) const noexcept {
    return static_cast<std::int64_t>(w) * h * dwell_ns + static_cast<std::int64_t>(h) * line_flyback_ns;
  }
  std::uint16_t max_value() const noexcept { return bits == 16 ? 65535 : 255; }
};

// Reads the `scan:` section (keys as the struct fields), checks ranges and consistency
// (min_dwell <= max_dwell, max ROI within the field).
void read_scan(Section& section, ScanLimits& out);

}  // namespace sempose::config
