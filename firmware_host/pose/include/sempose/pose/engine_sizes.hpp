// Every size the tracker's stages are built for, derived once at setup from the settings, the
// pattern and the scan field.
#pragma once

#include <algorithm>
#include <cmath>

#include "sempose/config/tracker_config.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/search_scale_levels.hpp"

namespace sempose::pose {

struct EngineSizes {
  int pattern_px = 0;         // square pattern side
  int roi_px = 0;             // ROI side: tracker.roi_size_px, at most the field
  int roi_fft_px = 0;         // largest ROI side loaded (FFT-friendly, >= roi_px)
  int half_fft_px = 0;        // FFT side of the 2×2-binned ROI level
  int search_factor = 8;      // start-search downsample
  int coarse_pattern_px = 0;  // pattern side at the coarse level
  int coarse_offset_px = 0;   // the coarse pattern's top-left inside the full pattern
  int coarse_max_w = 0, coarse_max_h = 0;  // largest coarse full-field frame (the smallest level's)
  int coarse_scan_w = 0, coarse_scan_h = 0;  // the scanned field at the coarse level (levels ≥ 1)

  static EngineSizes of(const config::TrackerConfig& cfg, int pattern_px, int field_w, int field_h) noexcept {
    EngineSizes s;
    s.pattern_px = pattern_px;
    s.roi_px = std::min({cfg.roi_size_px, field_w, field_h});
    s.roi_fft_px = good_fft_size(s.roi_px);
    s.half_fft_px = good_fft_size(s.roi_fft_px / 2);
    s.search_factor = cfg.search_downsample;
    s.coarse_pattern_px = pattern_px / s.search_factor;
    s.coarse_offset_px = (pattern_px - s.coarse_pattern_px * s.search_factor) / 2;
    // The start search's smallest scale level enlarges the coarse frame by 1/scale.
    const std::vector<double> levels = search_scale_levels(cfg);
    const double grow = 1.0 / *std::min_element(levels.begin(), levels.end());
    s.coarse_max_w = std::max(s.coarse_pattern_px, static_cast<int>(std::ceil(field_w / s.search_factor * grow)));
    s.coarse_max_h = std::max(s.coarse_pattern_px, static_cast<int>(std::ceil(field_h / s.search_factor * grow)));
    s.coarse_scan_w = std::max(s.coarse_pattern_px, field_w / s.search_factor);
    s.coarse_scan_h = std::max(s.coarse_pattern_px, field_h / s.search_factor);
    return s;
  }
  // A second coarse correlator for the levels below 1 when their enlarged frame needs a larger
  // FFT than the scanned one: level 1 (and the narrow search) then runs at the scanned size.
  bool wide_coarse() const noexcept {
    return good_fft_size(coarse_max_w) > good_fft_size(coarse_scan_w) ||
           good_fft_size(coarse_max_h) > good_fft_size(coarse_scan_h);
  }
};

}  // namespace sempose::pose
