#include "sempose/pose/motion_model.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/rt/angle.hpp"

namespace sempose::pose {

void MotionModel::accept(double x, double y, double phi, bool fresh, double dwell_ns, double score) noexcept {
  if (!fresh && have_prev_ && have_velocity_) {
    // Same share as the loss policy's running score mean: a few frames' memory.
    const double px2 = (x - pred_x_) * (x - pred_x_) + (y - pred_y_) * (y - pred_y_);
    const double dphi = rt::wrap_deg(phi - pred_phi_);
    innov_px2_ = have_innov_ ? 0.8 * innov_px2_ + 0.2 * px2 : px2;
    innov_deg2_ = have_innov_ ? 0.8 * innov_deg2_ + 0.2 * dphi * dphi : dphi * dphi;
    have_innov_ = true;
    ++innovations_since_fresh_;
    // The pose noise learns only from predictions made from two ROI poses: the first velocity
    // after a search spans the long full-field scan and overshoots once.
    if (innovations_since_fresh_ >= 2) {
      noise_px2_ = have_noise_ ? 0.8 * noise_px2_ + 0.2 * px2 : px2;
      noise_deg2_ = have_noise_ ? 0.8 * noise_deg2_ + 0.2 * dphi * dphi : dphi * dphi;
      level_px2_ = have_noise_ ? (1 - kLevelShare) * level_px2_ + kLevelShare * px2 : px2;
      level_deg2_ = have_noise_ ? (1 - kLevelShare) * level_deg2_ + kLevelShare * dphi * dphi : dphi * dphi;
      if (dwell_ns > 0)
        noise_dwell_ns_ = noise_dwell_ns_ > 0 ? (1 - kLevelShare) * noise_dwell_ns_ + kLevelShare * dwell_ns : dwell_ns;
      if (score > 0) noise_score_ = noise_score_ > 0 ? (1 - kLevelShare) * noise_score_ + kLevelShare * score : score;
      have_noise_ = true;
      ++noise_updates_;
    }
  }
  if (fresh) innovations_since_fresh_ = 0;
  // The next prediction is the model's full one: with a velocity from two poses in a row (or,
  // without velocity prediction, from any previous pose).
  have_velocity_ = !predict_velocity_ || (!fresh && have_prev_);
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

void MotionModel::hold() noexcept {
  vx_ = vy_ = vphi_ = 0;
  have_velocity_ = !predict_velocity_;
  predict();
}

void MotionModel::reset() noexcept {
  // Carried only once a stream had its own pose noise known (two innovations from ROI poses, as
  // pose_noise_known() asks of a new stream).
  carried_ = have_noise_ && noise_updates_ >= 2;
  innovations_since_fresh_ = 0;
  have_prev_ = false;
  have_velocity_ = false;
  vx_ = vy_ = vphi_ = 0;
}

double MotionModel::carried_noise_factor(double dwell_ns, double score) const noexcept {
  double v = 1.0;
  if (noise_dwell_ns_ > 0 && dwell_ns > 0) v *= std::max(1.0, noise_dwell_ns_ / dwell_ns);
  auto noise_over_signal = [](double r) {
    const double r2 = std::clamp(r * r, 1e-4, 1.0);
    return (1.0 - r2) / r2;
  };
  if (noise_score_ > 0 && score > 0)
    v *= std::max(1.0, noise_over_signal(score) / std::max(1e-6, noise_over_signal(noise_score_)));
  return std::sqrt(v);
}

void MotionModel::forget_noise() noexcept {
  reset();
  noise_px2_ = noise_deg2_ = level_px2_ = level_deg2_ = 0;
  have_noise_ = false;
  noise_updates_ = 0;
  carried_ = false;
  noise_dwell_ns_ = noise_score_ = 0;
}

void MotionModel::predict() noexcept {
  const bool v = predict_velocity_;
  pred_x_ = x_ + (v ? vx_ : 0);
  pred_y_ = y_ + (v ? vy_ : 0);
  pred_phi_ = rt::wrap_deg(phi_ + (v ? vphi_ : 0));
}

bool MotionModel::surprising(double x, double y, double phi, double wider) const noexcept {
  const double dpos = std::hypot(x - pred_x_, y - pred_y_);
  const double dphi = std::fabs(rt::wrap_deg(phi - pred_phi_));
  const bool known = have_velocity_ && have_innov_;
  const double lim_px = wider * std::max(kSurpriseFloorPx, known ? kSurpriseSigmas * std::sqrt(innov_px2_) : 0.0);
  const double lim_deg = wider * std::max(kSurpriseFloorDeg, known ? kSurpriseSigmas * std::sqrt(innov_deg2_) : 0.0);
  return dpos > lim_px || dphi > lim_deg;
}

double MotionModel::innovation_deg(double phi) const noexcept { return std::fabs(rt::wrap_deg(phi - pred_phi_)); }

MotionModel::ErrorGivenInnovation MotionModel::error_given_innovation(double d, double dphi, double sigma_m_px,
                                                                   double sigma_m_deg) const noexcept {
  const double pred_share = predict_velocity_ ? 5.0 : 1.0;  // σp² over the stream's σ²
  ErrorGivenInnovation r;
  const double m_px2 = sigma_m_px * sigma_m_px, p_px2 = pred_share * pose_noise_px() * pose_noise_px();
  const double m_deg2 = sigma_m_deg * sigma_m_deg, p_deg2 = pred_share * pose_noise_deg() * pose_noise_deg();
  if (m_px2 + p_px2 > 0) {
    r.offset_px = d * m_px2 / (m_px2 + p_px2);
    r.sd_px = std::sqrt(m_px2 * p_px2 / (m_px2 + p_px2));
  }
  if (m_deg2 + p_deg2 > 0) {
    r.offset_deg = dphi * m_deg2 / (m_deg2 + p_deg2);
    r.sd_deg = std::sqrt(m_deg2 * p_deg2 / (m_deg2 + p_deg2));
  }
  return r;
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
