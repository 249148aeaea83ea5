// ViSP's template tracker (visp_template_tracker.hpp) as the accuracy benchmark's peer on a
// SimHarness sequence (run_peer): the same recorded pattern and the same circle as sempose's
// mask, started at the truth on the first frame, tracking in a 256² crop centred on its last
// estimate — what a user would feed it from an SEM: a ROI, not the full field. Between frames
// its warp is carried into the new crop's coordinates, so it tracks as if it saw one image.
#pragma once

#include <algorithm>
#include <cmath>

#include "sempose/hal/frame.hpp"
#include "sempose/hal/image.hpp"
#include "sim_harness.hpp"
#include "visp_template_tracker.hpp"

namespace sempose::pose::testing {

class VispPeer {
 public:
  static constexpr int kRoiPx = 256;

  VispPeer(const hal::Image& pattern, double zone_radius_px, int pyramid_levels = 3)
      : tracker_(pattern.pixels.data(), pattern.width, pattern.bits, zone_radius_px, pyramid_levels) {}

  void start(double x, double y, double phi_deg, double scale) { tracker_.set_pose({x, y, phi_deg, scale}); }

  hal::Roi roi(int fw, int fh) const {
    const auto& p = tracker_.pose();
    const int w = std::min(kRoiPx, fw), h = std::min(kRoiPx, fh);
    const int x0 = std::clamp(static_cast<int>(std::lround(p.x_px - (w - 1) / 2.0)), 0, fw - w);
    const int y0 = std::clamp(static_cast<int>(std::lround(p.y_px - (h - 1) / 2.0)), 0, fh - h);
    return {x0, y0, w, h};
  }

  PeerPose track(const hal::Roi& roi, const hal::Pixel* px, int bits) {
    const VispTemplateTracker::Result r = tracker_.track(roi.x, roi.y, roi.w, roi.h, px, bits);
    PeerPose out;
    out.valid = r.valid;
    out.x_px = r.pose.x_px, out.y_px = r.pose.y_px, out.phi_deg = r.pose.phi_deg, out.scale = r.pose.scale;
    out.time_us = r.time_us;
    out.cpu_us = r.cpu_us;
    return out;
  }

 private:
  VispTemplateTracker tracker_;
};

}  // namespace sempose::pose::testing
