#include "sempose/pose/motion_model.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/rt/angle.hpp"

namespace sempose::pose {

void MotionModel::accept(double x, double y, double phi, bool fresh) noexcept {
  if (!fresh && have_prev_) {
    vx_ = x - x_;
    vy_ = y - y_;
    vphi_ = rt::wrap_deg(phi - phi_);
  } else {
    vx_ = vy_ = vphi_ = 0;
  }
  x_ = x;
  y_ = y;
  phi_ = phi;
  last_angle_ = {true, phi};
  have_prev_ = true;
  predict();
}

void MotionModel::coast() noexcept {
  x_ = pred_x_;
  y_ = pred_y_;
  phi_ = pred_phi_;
  predict();
}

void MotionModel::reset() noexcept {
  have_prev_ = false;
  vx_ = vy_ = vphi_ = 0;
}

void MotionModel::predict() noexcept {
  const bool v = predict_velocity_;
  pred_x_ = x_ + (v ? vx_ : 0);
  pred_y_ = y_ + (v ? vy_ : 0);
  pred_phi_ = rt::wrap_deg(phi_ + (v ? vphi_ : 0));
}

Roi MotionModel::window_at_prediction(int rw, int rh, int field_w, int field_h) const noexcept {
  const int rx = std::clamp(static_cast<int>(std::lround(pred_x_ - (rw - 1) / 2.0)), 0, field_w - rw);
  const int ry = std::clamp(static_cast<int>(std::lround(pred_y_ - (rh - 1) / 2.0)), 0, field_h - rh);
  return {rx, ry, rw, rh};
}

bool MotionModel::prediction_outside(int field_w, int field_h) const noexcept {
  return pred_x_ < 0.0 || pred_y_ < 0.0 || pred_x_ > field_w - 1 || pred_y_ > field_h - 1;
}

}  // namespace sempose::pose
