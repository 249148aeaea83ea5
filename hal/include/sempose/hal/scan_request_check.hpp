// Validation of a ScanRequest against the scan generator's limits, shared by every source.
// The full field is always allowed (the tracker's start search), even above max_roi_w/h;
// other ROIs must fit max_roi and lie inside the field. The dwell is rounded to the nearest
// multiple of dwell_step_ns, then must lie in [min_dwell_ns, max_dwell_ns].
#pragma once

#include <cstddef>

#include "sempose/hal/scan_source.hpp"

namespace sempose::hal {

inline StartResult check_scan_request(const ScanLimits& lim, const ScanRequest& req, std::size_t capacity_pixels,
                                      std::uint32_t& dwell_ns) noexcept {
  const Roi& r = req.roi;
  const bool full = lim.is_full_field(r.x, r.y, r.w, r.h);
  if (r.w <= 0 || r.h <= 0 || r.x < 0 || r.y < 0 || r.x > lim.field_w - r.w || r.y > lim.field_h - r.h) {
    return StartResult::kBadRequest;
  }
  if (!full && (r.w > lim.max_roi_w || r.h > lim.max_roi_h)) return StartResult::kBadRequest;
  const std::uint64_t rounded = lim.round_dwell_ns(req.dwell_ns);
  if (rounded < lim.min_dwell_ns || rounded > lim.max_dwell_ns) return StartResult::kBadRequest;
  if (static_cast<std::size_t>(r.w) * static_cast<std::size_t>(r.h) > capacity_pixels) return StartResult::kNoRoom;
  dwell_ns = static_cast<std::uint32_t>(rounded);
  return StartResult::kStarted;
}

}  // namespace sempose::hal
