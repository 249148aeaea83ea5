#pragma once
// The pose a raster scan shows of a target that moves while it is scanned. Rows follow one
// another in time, so a target moving v px/s shows, on each row, displaced by v × the row's
// time since the pose's row: sheared by v_x and stretched by v_y. The rigid fit (position,
// angle, scale, gain, offset) takes the part of that displacement its own parameters can
// express as the target's pose: noise-free, 200 px/s and 50 µs rows turned the needle tip
// +0.63°, the lamella on its post +0.26° and the lamella +0.22° (pose_accuracy_bench fast rows:
// the largest part of their angle error). Linearised about the true pose over the pattern's
// support (least squares with the pattern's gradients: the fit's own first-order response), the
// bias is linear in the velocity (and the turn rate) and in the direction the rows run through
// the pattern; six 6-vectors per pattern at setup, contracted per frame (RT: no allocation).
#include <array>

namespace sempose::pose {

class PatternBank;

// The bias a moving target's scan adds to its measured pose.
struct ScanMotionBias {
  double x_px = 0, y_px = 0, phi_deg = 0;
  double scale = 0;  // relative: the measured scale is (1 + scale) × the target's
};

class ScanMotionResponse {
 public:
  ScanMotionResponse() = default;
  // Setup: from the bank's pattern at angle 0 (its support, as the fit scores it).
  explicit ScanMotionResponse(const PatternBank& bank);
  // A target at phi_deg and scale moving (vx, vy) px and turning turn_deg per scanned row (its
  // velocity × one row's time).
  ScanMotionBias bias(double phi_deg, double scale, double vx_px_per_row, double vy_px_per_row,
                      double turn_deg_per_row) const noexcept;
  bool valid() const noexcept { return valid_; }

 private:
  // K_ij = H⁻¹ Σ J (G·e_i) u_j over the support (i: the displacement's pattern axis or the
  // rotation field, j: the pattern axis the row offset runs along), ij = xx, xy, yx, yy, θx, θy;
  // each over (x, y, θ, scale, gain, offset).
  std::array<std::array<double, 6>, 6> k_{};
  bool valid_ = false;
};

}  // namespace sempose::pose
