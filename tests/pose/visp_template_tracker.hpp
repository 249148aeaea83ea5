// ViSP's template tracker behind a plain interface (no ViSP or sempose types), so that ViSP's
// headers, which do not compile as C++20 with GCC 12 (template-id constructors in vpArray2D),
// stay in one C++17 file: visp_template_tracker.cpp. Benchmark only; never linked into sempose.
//   vpTemplateTrackerZNCCInverseCompositional on vpTemplateTrackerWarpSRT (scale, rotation,
//   translation), 3 pyramid levels (the benchmark's setting; --visp-levels), every template
//   pixel, zone = a circle about the pattern centre (a fan of 32 triangles).
// Poses are in sempose's convention (visp_peer.hpp converts): the pattern centre's field
// position, φ counter-clockwise on screen, scale relative to the pattern.
#pragma once

#include <cstdint>
#include <memory>

namespace sempose::pose::testing {

class VispTemplateTracker {
 public:
  struct Pose {
    double x_px = 0, y_px = 0, phi_deg = 0, scale = 1;
  };
  struct Result {
    bool valid = false;  // false: ViSP threw (the zone left the image) or diverged; pose = the last one
    Pose pose;
    double time_us = 0;  // track() alone, wall clock
    double cpu_us = 0;   // the same on the thread's CPU clock
  };

  // pattern: P×P pixels of `bits` bits (16-bit values are shifted to 8: ViSP tracks 8-bit images).
  VispTemplateTracker(const std::uint16_t* pattern, int size_px, int bits, double zone_radius_px, int pyramid_levels = 3);
  ~VispTemplateTracker();
  VispTemplateTracker(const VispTemplateTracker&) = delete;
  VispTemplateTracker& operator=(const VispTemplateTracker&) = delete;

  void set_pose(const Pose& p);
  const Pose& pose() const;
  // One frame: a w×h crop whose top-left pixel is field pixel (x0, y0). The warp starts from the
  // current pose carried into the crop's coordinates.
  Result track(int x0, int y0, int w, int h, const std::uint16_t* pixels, int bits);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sempose::pose::testing
