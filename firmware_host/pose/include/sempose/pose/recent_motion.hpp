#pragma once
// How fast the target moved over its last followed poses, whatever their frames were (a search
// frame's pose included) and kept through a loss: the motion model forgets its velocity at a
// loss and has none from a search frame to the next ROI frame, while the search after a loss
// needs to know whether the target was moving when its long field scan passed over it
// (Tracker::Impl::sheared_by_motion). Over the last kPoses poses, not two: a velocity from two
// ROI poses a few ms apart carries their noise (1 px at 2.5 e⁻/px is ~300 px/s), one over
// ≥ kMinSpan_s averages it down. RT: a fixed ring, no allocation.
#include <array>
#include <cmath>

#include "sempose/rt/angle.hpp"

namespace sempose::pose {

class RecentMotion {
 public:
  static constexpr int kPoses = 8;
  static constexpr double kMinSpan_s = 0.02;  // shorter: the poses' noise, not the motion
  static constexpr double kMaxAge_s = 0.5;    // older: the target may have done anything since

  // A followed pose, at the time the beam passed it.
  void note(double t_s, double x_px, double y_px, double phi_deg) noexcept {
    if (n_ > 0 && !(t_s > ring_[newest()].t_s)) return;  // a standing or backward clock
    head_ = (head_ + 1) % kPoses;
    ring_[head_] = {t_s, x_px, y_px, phi_deg};
    if (n_ < kPoses) ++n_;
  }
  void forget() noexcept { n_ = 0; }

  // Speed (px/s) and turn rate (°/s, summed over the steps so a spin is not folded at 180°)
  // over the kept poses, judged at now_s; false when they are too few, too close in time or too old.
  bool rates(double now_s, double& speed_px_s, double& turn_deg_s) const noexcept {
    speed_px_s = turn_deg_s = 0;
    if (n_ < 2 || now_s - ring_[newest()].t_s > kMaxAge_s) return false;
    const int oldest = (head_ - n_ + 1 + kPoses) % kPoses;
    const Pose& a = ring_[oldest];
    const Pose& b = ring_[newest()];
    const double span = b.t_s - a.t_s;
    if (!(span >= kMinSpan_s)) return false;
    double turned = 0;
    for (int k = 1; k < n_; ++k) {
      const Pose& p = ring_[(oldest + k - 1) % kPoses];
      const Pose& q = ring_[(oldest + k) % kPoses];
      turned += rt::wrap_deg(q.phi_deg - p.phi_deg);
    }
    speed_px_s = std::hypot(b.x_px - a.x_px, b.y_px - a.y_px) / span;
    turn_deg_s = std::fabs(turned) / span;
    return true;
  }

 private:
  struct Pose {
    double t_s = 0, x_px = 0, y_px = 0, phi_deg = 0;
  };
  int newest() const noexcept { return head_; }
  std::array<Pose, kPoses> ring_{};
  int head_ = kPoses - 1, n_ = 0;
};

}  // namespace sempose::pose
