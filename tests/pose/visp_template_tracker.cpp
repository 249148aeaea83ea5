// See visp_template_tracker.hpp. ViSP's SRT warp maps a template point X (pattern pixels, origin
// at the pattern's top-left) to s·R(θ)·X + t in the image: it turns about the image origin, with
// θ clockwise on screen (y down). sempose's pose is the pattern centre c = ((P−1)/2, (P−1)/2)
// with φ counter-clockwise, so
//   φ = −θ,   (x, y) = crop origin + s·R(θ)·c + t,   t = (x, y) − crop origin − s·R(θ)·c.
#include "visp_template_tracker.hpp"

#include <visp3/core/vpImage.h>
#include <visp3/tt/vpTemplateTrackerTriangle.h>
#include <visp3/tt/vpTemplateTrackerWarpSRT.h>
#include <visp3/tt/vpTemplateTrackerZNCCInverseCompositional.h>
#include <visp3/tt/vpTemplateTrackerZone.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>

namespace sempose::pose::testing {

struct VispTemplateTracker::Impl {
  vpTemplateTrackerWarpSRT warp;
  vpTemplateTrackerZNCCInverseCompositional tracker{&warp};
  vpImage<unsigned char> image;
  double c = 0;
  Pose pose;
};

VispTemplateTracker::VispTemplateTracker(const std::uint16_t* pattern, int P, int bits, double zone_radius_px,
                                         int pyramid_levels)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.c = (P - 1) / 2.0;
  vpImage<unsigned char> ref(static_cast<unsigned>(P), static_cast<unsigned>(P));
  const int shift = bits > 8 ? 8 : 0;
  for (int y = 0; y < P; ++y)
    for (int x = 0; x < P; ++x)
      ref[y][x] = static_cast<unsigned char>(std::min(255, pattern[static_cast<std::size_t>(y) * P + x] >> shift));
  m.tracker.setSampling(1, 1);
  m.tracker.setLambda(0.001);
  m.tracker.setIterationMax(50);
  m.tracker.setPyramidal(static_cast<unsigned>(pyramid_levels), 0);  // coarsest first, down to full resolution
  vpTemplateTrackerZone zone;
  constexpr int kFan = 32;
  const double r = zone_radius_px;
  for (int k = 0; k < kFan; ++k) {  // vpImagePoint is (row, column)
    const double a0 = 2 * M_PI * k / kFan, a1 = 2 * M_PI * (k + 1) / kFan;
    zone.add(vpTemplateTrackerTriangle(vpImagePoint(m.c, m.c), vpImagePoint(m.c + r * std::sin(a0), m.c + r * std::cos(a0)),
                                       vpImagePoint(m.c + r * std::sin(a1), m.c + r * std::cos(a1))));
  }
  m.tracker.initFromZone(ref, zone);
}

VispTemplateTracker::~VispTemplateTracker() = default;

void VispTemplateTracker::set_pose(const Pose& p) { impl_->pose = p; }
const VispTemplateTracker::Pose& VispTemplateTracker::pose() const { return impl_->pose; }

VispTemplateTracker::Result VispTemplateTracker::track(int x0, int y0, int w, int h, const std::uint16_t* px, int bits) {
  Impl& m = *impl_;
  if (static_cast<int>(m.image.getWidth()) != w || static_cast<int>(m.image.getHeight()) != h)
    m.image.resize(static_cast<unsigned>(h), static_cast<unsigned>(w));
  const int shift = bits > 8 ? 8 : 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) m.image[y][x] = static_cast<unsigned char>(std::min(255, px[static_cast<std::size_t>(y) * w + x] >> shift));
  const double th = -m.pose.phi_deg * M_PI / 180.0, cs = std::cos(th), sn = std::sin(th), s = m.pose.scale;
  vpColVector p(4);
  p[0] = s - 1.0;
  p[1] = th;
  p[2] = m.pose.x_px - x0 - s * (cs * m.c - sn * m.c);
  p[3] = m.pose.y_px - y0 - s * (sn * m.c + cs * m.c);
  Result out;
  const auto t0 = std::chrono::steady_clock::now();
  timespec c0{}, c1{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c0);
  try {
    m.tracker.setp(p);
    m.tracker.track(m.image);
    const vpColVector q = m.tracker.getp();
    const double s1 = 1.0 + q[0], t = q[1], c = std::cos(t), n = std::sin(t);
    const double x = s1 * (c * m.c - n * m.c) + q[2] + x0, y = s1 * (n * m.c + c * m.c) + q[3] + y0;
    out.valid = std::isfinite(x) && std::isfinite(y) && std::isfinite(t) && s1 > 0.2 && s1 < 5 && !m.tracker.getDiverge();
    if (out.valid) m.pose = {x, y, std::remainder(-t * 180.0 / M_PI, 360.0), s1};
  } catch (...) {  // vpTrackingException: the warped zone left the image
    out.valid = false;
  }
  out.time_us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &c1);
  out.cpu_us = (c1.tv_sec - c0.tv_sec) * 1e6 + (c1.tv_nsec - c0.tv_nsec) * 1e-3;
  out.pose = m.pose;
  return out;
}

}  // namespace sempose::pose::testing
