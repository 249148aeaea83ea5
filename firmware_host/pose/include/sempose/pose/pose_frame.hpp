// What the pose engine takes per frame, in its own small types (it does not depend on the
// hardware layer; the pipeline and the offline runner convert their frames to this).
#pragma once

#include <cstdint>

#include "sempose/config/scan_config.hpp"

namespace sempose::pose {

// A rectangle of the scan field, in full-field pixels (the scan vocabulary's one ROI type).
using Roi = config::Roi;

// Where the other targets of the same run are followed (their last followed poses, full-field
// pixels). Several targets may share a pattern (two identical tips, two lamellae): a start
// search must not hand a target the object another target already holds.
inline constexpr int kMaxHeldPlaces = 7;
struct HeldPlaces {
  int count = 0;
  double x_px[kMaxHeldPlaces]{};
  double y_px[kMaxHeldPlaces]{};
  // The search keeps to this circle when within_r_px > 0 (a start area told in the config, until
  // the target is first TRACKING; set by the tracker, not by the caller).
  double within_x_px = 0, within_y_px = 0, within_r_px = 0;
};

struct PoseFrame {
  const std::uint16_t* pixels = nullptr;  // roi.w × roi.h, row-major, row stride roi.w
  Roi roi;                                // where it was scanned
  std::int32_t field_w = 0, field_h = 0;  // the full scan field (0: unchanged)
  std::uint8_t bits = 8;                  // significant bits per pixel
  bool bad = false;                       // the source flagged the frame (overrun, torn, missed sync)
  std::int64_t t_scan_start_ns = 0, t_scan_end_ns = 0;  // the pose is timed at mid-scan
  std::uint32_t dwell_ns = 0;             // pixel dwell of this scan (0: not known)
  HeldPlaces held_by_others;              // the run's other targets (none: a single target)
};

}  // namespace sempose::pose
