#include <string>

#include "sempose/config/reader.hpp"
#include "sempose/config/scan_config.hpp"

namespace sempose::config {

void read_scan(Section& s, ScanLimits& out) {
  constexpr std::int32_t kMaxSide = 16384;
  s.opt("field_w", out.field_w, 16, kMaxSide);
  s.opt("field_h", out.field_h, 16, kMaxSide);
  s.opt("max_roi_w", out.max_roi_w, 8, kMaxSide);
  s.opt("max_roi_h", out.max_roi_h, 8, kMaxSide);
  s.opt("min_dwell_ns", out.min_dwell_ns, 1u, 100'000'000u);
  s.opt("max_dwell_ns", out.max_dwell_ns, 1u, 100'000'000u);
  s.opt("dwell_step_ns", out.dwell_step_ns, 1u, 1'000'000u);
  s.opt("line_flyback_ns", out.line_flyback_ns, 0u, 100'000'000u);
  int bits = out.bits;
  s.opt("bits", bits, 8, 16);
  if (bits != 8 && bits != 16) s.error("bits", std::to_string(bits) + " is not one of: 8, 16");
  else out.bits = static_cast<std::uint8_t>(bits);
  if (out.min_dwell_ns > out.max_dwell_ns) {
    s.error("min_dwell_ns", std::to_string(out.min_dwell_ns) + " is above max_dwell_ns (" +
                                std::to_string(out.max_dwell_ns) + ")");
  } else if (const std::uint64_t step = out.step_ns();
             (out.min_dwell_ns + step - 1) / step * step > out.max_dwell_ns) {
    // Dwells are multiples of the step: with none in the limits every scan request was refused
    // (`sempose run` exit 0 with frames=0, scan_errors=1).
    s.error("dwell_step_ns", std::to_string(out.dwell_step_ns) + " has no multiple in min_dwell_ns..max_dwell_ns [" +
                                 std::to_string(out.min_dwell_ns) + ", " + std::to_string(out.max_dwell_ns) +
                                 "]: no dwell could be scanned");
  }
  // A max ROI left at its default follows a smaller field; one set explicitly must fit.
  if (!s.has("max_roi_w") && out.max_roi_w > out.field_w) out.max_roi_w = out.field_w;
  if (!s.has("max_roi_h") && out.max_roi_h > out.field_h) out.max_roi_h = out.field_h;
  if (out.max_roi_w > out.field_w) {
    s.error("max_roi_w", std::to_string(out.max_roi_w) + " is wider than field_w (" +
                             std::to_string(out.field_w) + ")");
  }
  if (out.max_roi_h > out.field_h) {
    s.error("max_roi_h", std::to_string(out.max_roi_h) + " is taller than field_h (" +
                             std::to_string(out.field_h) + ")");
  }
}

}  // namespace sempose::config
