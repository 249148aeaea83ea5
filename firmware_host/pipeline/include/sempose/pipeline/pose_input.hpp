// The one place where the hardware layer's frames and images become the pose engine's
// own input types (the pose engine does not depend on hal). Header-only, RT-safe: plain copies.
#pragma once

#include <utility>

#include "sempose/hal/frame.hpp"
#include "sempose/hal/image.hpp"
#include "sempose/pose/pattern_image.hpp"
#include "sempose/pose/pose_frame.hpp"

namespace sempose::pipeline {

inline pose::PoseFrame to_pose_frame(const hal::FrameMeta& meta, const hal::Pixel* pixels) noexcept {
  pose::PoseFrame f;
  f.pixels = pixels;
  f.roi = meta.roi;
  f.field_w = meta.field_w;
  f.field_h = meta.field_h;
  f.bits = meta.bits;
  f.bad = meta.status == hal::FrameStatus::kBad;
  f.t_scan_start_ns = meta.t_scan_start_ns;
  f.t_scan_end_ns = meta.t_scan_end_ns;
  f.dwell_ns = meta.dwell_ns;
  return f;
}

inline pose::PatternImage to_pattern_image(hal::Image image) {
  return {image.width, image.height, std::move(image.pixels)};
}

}  // namespace sempose::pipeline
