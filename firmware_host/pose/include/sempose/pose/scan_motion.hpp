#pragma once
// The pose a raster scan shows of a target that moves while it is scanned. Rows follow one
// another in time, so a target moving v px/s shows, on each row, displaced by v × the row's
// time since the pose's row: sheared by v_x and stretched by v_y. The rigid fit (position,
// angle, scale, gain, offset) takes the part of that displacement its own parameters can
// express as the target's pose: noise-free, 200 px/s and 50 µs rows turned the needle tip
// +0.63°, the lamella on its post +0.26° and the lamella +0.22° (pose_accuracy_bench fast rows:
// the largest part of their angle error). Linearised about the true pose over the support of the
// bank's copy at the target's angle (least squares with that copy's gradients: the fit's own
// first-order response; the copy at 0° turned was 2× off at 30–45° where a pattern's support is
// not round, the lamella on its post), the bias is linear in the velocity and the turn rate: three
// 6-vectors per angle sampled at setup (every kAngleStrideDeg), read per frame (RT: no allocation).
#include <array>
#include <vector>

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
  // Setup: from the bank's copies (their supports, as the fit scores them).
  explicit ScanMotionResponse(const PatternBank& bank);
  // A target at phi_deg and scale moving (vx, vy) px and turning turn_deg per scanned row (its
  // velocity × one row's time).
  ScanMotionBias bias(double phi_deg, double scale, double vx_px_per_row, double vy_px_per_row,
                      double turn_deg_per_row) const noexcept;
  bool valid() const noexcept { return !k_.empty(); }

 private:
  // Per sampled angle: K_i = H⁻¹ Σ J (G·e_i) u_y over the copy's support, i = the displacement
  // along the field's x, along y, the rotation field (u_y: a pixel's row offset from the pose's
  // row); each over (x, y, θ, scale, gain, offset).
  using Response = std::array<std::array<double, 6>, 3>;
  std::vector<Response> k_;
  double step_deg_ = 0;
};

}  // namespace sempose::pose
