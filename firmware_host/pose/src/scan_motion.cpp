#include "sempose/pose/scan_motion.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <numbers>

#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {

ScanMotionResponse::ScanMotionResponse(const PatternBank& bank) {
  const int n = bank.size_px();
  const float* p = bank.pattern(0);  // zero outside its support
  const double c = 0.5 * (n - 1);
  const auto at = [&](int x, int y) { return static_cast<double>(p[static_cast<long>(y) * n + x]); };
  double mean = 0;
  long count = 0;
  for (int y = 1; y < n - 1; ++y)
    for (int x = 1; x < n - 1; ++x)
      if (at(x, y) != 0) {
        mean += at(x, y);
        ++count;
      }
  if (count < 64) return;
  mean /= static_cast<double>(count);
  Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> t = Eigen::Matrix<double, 6, 6>::Zero();
  for (int y = 1; y < n - 1; ++y)
    for (int x = 1; x < n - 1; ++x) {
      // Gradients only where the pixel and its four neighbours are inside the support.
      if (at(x, y) == 0 || at(x - 1, y) == 0 || at(x + 1, y) == 0 || at(x, y - 1) == 0 || at(x, y + 1) == 0) continue;
      const double ux = x - c, uy = y - c;
      const double gx = 0.5 * (at(x + 1, y) - at(x - 1, y)), gy = 0.5 * (at(x, y + 1) - at(x, y - 1));
      // The pose's fields at u: translation, rotation (φ counter-clockwise on screen moves u by
      // (u_y, -u_x) per radian), scale (u), then gain and offset.
      Eigen::Matrix<double, 6, 1> j;
      j << gx, gy, gx * uy - gy * ux, gx * ux + gy * uy, at(x, y) - mean, 1.0;
      h.noalias() += j * j.transpose();
      t.col(0) += j * (gx * ux);
      t.col(1) += j * (gx * uy);
      t.col(2) += j * (gy * ux);
      t.col(3) += j * (gy * uy);
      const double turn = gx * uy - gy * ux;  // the rotation field's change of the pattern at u
      t.col(4) += j * (turn * ux);
      t.col(5) += j * (turn * uy);
    }
  // The walk fits position and angle at the tracked scale (the scale probe reads scale after
  // it): the scale is not a parameter of the fit whose bias this is.
  h.row(3).setZero();
  h.col(3).setZero();
  h(3, 3) = 1.0;
  t.row(3).setZero();
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(h);
  if (ldlt.info() != Eigen::Success) return;
  const Eigen::Matrix<double, 6, 6> k = ldlt.solve(t);
  if (!k.allFinite()) return;
  for (int ij = 0; ij < 6; ++ij)
    for (int r = 0; r < 6; ++r) k_[static_cast<std::size_t>(ij)][static_cast<std::size_t>(r)] = k(r, ij);
  valid_ = true;
}

ScanMotionBias ScanMotionResponse::bias(double phi_deg, double scale, double vx_px_per_row, double vy_px_per_row,
                                        double turn_deg_per_row) const noexcept {
  if (!valid_) return {};
  const double rad = phi_deg * (std::numbers::pi / 180.0), cs = std::cos(rad), sn = std::sin(rad);
  // Pattern u lies at s·R u from the pose (R = [[cos, sin], [-sin, cos]], y down): its row offset
  // is s·(ρ·u) with ρ = R's second row. A shift v per row displaces it by v × that offset, in
  // pattern axes Rᵀv / s (the scale cancels); a turn ω per row by ω × that offset along the
  // rotation field (the scale stays).
  const double vx_p = cs * vx_px_per_row - sn * vy_px_per_row, vy_p = sn * vx_px_per_row + cs * vy_px_per_row;
  const double rho_x = -sn, rho_y = cs;
  const double w_turn = scale * turn_deg_per_row * (std::numbers::pi / 180.0);
  const double w[6] = {vx_p * rho_x, vx_p * rho_y, vy_p * rho_x, vy_p * rho_y, w_turn * rho_x, w_turn * rho_y};
  double d[6] = {};
  for (int ij = 0; ij < 6; ++ij)
    for (int r = 0; r < 6; ++r) d[r] += w[ij] * k_[static_cast<std::size_t>(ij)][static_cast<std::size_t>(r)];
  // The pattern-axis shift back to the field's axes: s·R.
  ScanMotionBias b;
  b.x_px = scale * (cs * d[0] + sn * d[1]);
  b.y_px = scale * (-sn * d[0] + cs * d[1]);
  b.phi_deg = d[2] * (180.0 / std::numbers::pi);
  b.scale = d[3];
  return b;
}

}  // namespace sempose::pose
