#include "sempose/pose/scan_motion.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {
namespace {

// The response changes with the copy's support and interpolation, slowly with angle: sampled
// every 5° (72 angles, ~50 ms a pattern at setup; every 1° took 0.25 s for no measurable change).
constexpr double kAngleStrideDeg = 5.0;

// One copy's response, false when its support is too small or the fit's normal matrix singular.
bool response_of(const float* p, int n, std::array<std::array<double, 6>, 3>& out) {
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
  if (count < 64) return false;
  mean /= static_cast<double>(count);
  Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 3> t = Eigen::Matrix<double, 6, 3>::Zero();
  for (int y = 1; y < n - 1; ++y)
    for (int x = 1; x < n - 1; ++x) {
      // Gradients only where the pixel and its four neighbours are inside the support.
      if (at(x, y) == 0 || at(x - 1, y) == 0 || at(x + 1, y) == 0 || at(x, y - 1) == 0 || at(x, y + 1) == 0) continue;
      const double ux = x - c, uy = y - c;
      const double gx = 0.5 * (at(x + 1, y) - at(x - 1, y)), gy = 0.5 * (at(x, y + 1) - at(x, y - 1));
      // The pose's fields at u: translation, rotation (φ counter-clockwise on screen moves u by
      // (u_y, -u_x) per radian, y down), scale (u), then gain and offset.
      Eigen::Matrix<double, 6, 1> j;
      const double turn = gx * uy - gy * ux;
      j << gx, gy, turn, gx * ux + gy * uy, at(x, y) - mean, 1.0;
      h.noalias() += j * j.transpose();
      // u's row lies u_y rows from the pose's: displaced by u_y × (v_x, v_y, the turn).
      t.col(0) += j * (gx * uy);
      t.col(1) += j * (gy * uy);
      t.col(2) += j * (turn * uy);
    }
  // The walk fits position and angle at the tracked scale (the scale probe reads scale after
  // it): the scale is not a parameter of the fit whose bias this is.
  h.row(3).setZero();
  h.col(3).setZero();
  h(3, 3) = 1.0;
  t.row(3).setZero();
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(h);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, 6, 3> k = ldlt.solve(t);
  if (!k.allFinite()) return false;
  for (int i = 0; i < 3; ++i)
    for (int r = 0; r < 6; ++r) out[static_cast<std::size_t>(i)][static_cast<std::size_t>(r)] = k(r, i);
  return true;
}

}  // namespace

ScanMotionResponse::ScanMotionResponse(const PatternBank& bank) {
  const int angles = bank.angles();
  if (angles <= 0) return;
  const double bank_step = 360.0 / angles;
  const int stride = std::max(1, static_cast<int>(std::lround(kAngleStrideDeg / bank_step)));
  std::vector<Response> k;
  for (int j = 0; j < angles; j += stride) {
    Response r{};
    if (!response_of(bank.pattern(j), bank.size_px(), r)) return;  // not valid: no correction
    k.push_back(r);
  }
  k_ = std::move(k);
  step_deg_ = bank_step * stride;
}

ScanMotionBias ScanMotionResponse::bias(double phi_deg, double scale, double vx_px_per_row, double vy_px_per_row,
                                        double turn_deg_per_row) const noexcept {
  if (k_.empty() || !std::isfinite(phi_deg)) return {};
  // The sampled copy nearest the target's angle (its response turns slowly with the angle).
  const long n = static_cast<long>(k_.size());
  const long i = ((std::lround(phi_deg / step_deg_) % n) + n) % n;
  const Response& r = k_[static_cast<std::size_t>(i)];
  // The copy is the target as the field shows it at scale 1: copy pixel u lies at s·u from the
  // pose, s·u_y rows from the pose's row. A shift v per row displaces it by v·s·u_y, v·u_y in the
  // copy's pixels (the scale cancels); a turn ω per row by ω·s·u_y along the rotation field.
  const double w[3] = {vx_px_per_row, vy_px_per_row, scale * turn_deg_per_row * (std::numbers::pi / 180.0)};
  // The turn's share of the position is left out: taken out, it made the spinning rows' position
  // worse (pose_accuracy_bench --quick, needle tip spin at 20 e-/px 3.24 -> 5.12x the bound, the
  // lamella's 4.12 -> 5.01x) where without it they stay as uncorrected; its angle share is kept.
  double d[6] = {};
  for (int c = 0; c < 3; ++c)
    for (int p = c == 2 ? 2 : 0; p < 6; ++p) d[p] += w[c] * r[static_cast<std::size_t>(c)][static_cast<std::size_t>(p)];
  ScanMotionBias b;
  b.x_px = scale * d[0];  // the copy's pixels to the field's
  b.y_px = scale * d[1];
  b.phi_deg = d[2] * (180.0 / std::numbers::pi);
  b.scale = d[3];
  return b;
}

}  // namespace sempose::pose
