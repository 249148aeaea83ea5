// What the scan generator can do: field size, ROI and dwell limits, line flyback, output
// bits. YAML section `scan:` (read_scan). hal::ScanLimits is an alias of this struct.
#pragma once

#include <cstdint>

namespace sempose::config {

class Section;

// A rectangle of the scan field, in full-field pixels; (x, y) is its top-left pixel. The one
// ROI type of the scan source (hal::Roi) and the pose engine (pose::Roi).
struct Roi {
  std::int32_t x = 0;
  std::int32_t y = 0;
  std::int32_t w = 0;
  std::int32_t h = 0;
  friend bool operator==(const Roi&, const Roi&) = default;
};

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
  // The step dwells are multiples of: dwell_step_ns, where 0 (any dwell) means 1 ns.
  std::uint64_t step_ns() const noexcept { return dwell_step_ns == 0 ? 1 : dwell_step_ns; }
  // The dwell the generator runs for a requested one: the nearest multiple of dwell_step_ns
  // (halves round up). Range checks are the caller's.
  std::uint64_t round_dwell_ns(std::uint64_t dwell_ns) const noexcept {
    const std::uint64_t step = step_ns();
    return (dwell_ns + step / 2) / step * step;
  }
  // A scan of the whole field (the start search), which is allowed above max_roi_w/h.
  bool is_full_field(std::int32_t x, std::int32_t y, std::int32_t w, std::int32_t h) const noexcept {
    return x == 0 && y == 0 && w >= field_w && h >= field_h;
  }
};

// Reads the `scan:` section (keys as the struct fields), checks ranges and consistency
// (min_dwell <= max_dwell, max ROI within the field).
void read_scan(Section& section, ScanLimits& out);

}  // namespace sempose::config
