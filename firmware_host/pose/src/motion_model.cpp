#include "sempose/pose/motion_model.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/rt/angle.hpp"

namespace sempose::pose {

void MotionModel::accept(double x, double y, double phi, bool fresh, double dwell_ns, double score) noexcept {
  // A pose the motion seen so far does not explain (surprising(): a bounce, a start, a stop),
  // accepted all the same: the line through the poses before it is broken, so the next rate
  // starts again from this pose and the one before it. Fitted over four poses, a bounce at
  // 4 px a frame was predicted 8, 8 and 4 px off on three frames in a row (the two-pose rate:
  // one frame), and the inflated pose noise made the procedural lamella's good poses UNCERTAIN
  // for nine frames (pose_accuracy_bench --quick, lamella fast 2.5 e-/px: 91.7 -> 76.7 %).
  const bool line_broken = !fresh && have_prev_ && have_velocity_ && hist_n_ > 2 && surprising(x, y, phi);
  if (!fresh && have_prev_ && have_velocity_) {
    // Same share as the loss policy's running score mean: a few frames' memory.
    const double px2 = (x - pred_x_) * (x - pred_x_) + (y - pred_y_) * (y - pred_y_);
    const double dphi = rt::wrap_deg(phi - pred_phi_);
    innov_px2_ = have_innov_ ? 0.8 * innov_px2_ + 0.2 * px2 : px2;
    innov_deg2_ = have_innov_ ? 0.8 * innov_deg2_ + 0.2 * dphi * dphi : dphi * dphi;
    have_innov_ = true;
    ++innovations_since_fresh_;
    // The pose noise learns only from predictions made from two ROI poses: the first velocity
    // after a search spans the long full-field scan and overshoots once. It learns the
    // innovation of the two-pose prediction (cv_*), whatever rate the ROI follows: its figures
    // (E|d|² = 12σ² + |a|²) and the UNCERTAIN rule's calibration stay as measured. Learnt from
    // the fitted line's innovations (scaled by 6 / (1 + q)), a bounce's three lagging frames
    // inflated it, and the lamella fast at 2.5 e-/px went 91.7 -> 76.7 % TRACKING.
    if (innovations_since_fresh_ >= 2) {
      const double n_px2 = (x - cv_x_) * (x - cv_x_) + (y - cv_y_) * (y - cv_y_);
      const double cv_dphi = rt::wrap_deg(phi - cv_phi_);
      const double n_deg2 = cv_dphi * cv_dphi;
      noise_px2_ = have_noise_ ? 0.8 * noise_px2_ + 0.2 * n_px2 : n_px2;
      noise_deg2_ = have_noise_ ? 0.8 * noise_deg2_ + 0.2 * n_deg2 : n_deg2;
      level_px2_ = have_noise_ ? (1 - kLevelShare) * level_px2_ + kLevelShare * n_px2 : n_px2;
      level_deg2_ = have_noise_ ? (1 - kLevelShare) * level_deg2_ + kLevelShare * n_deg2 : n_deg2;
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
  if (fresh || !have_prev_) {
    hist_n_ = 0;
    hist_from_search_ = fresh;
  } else if (line_broken) {
    hist_x_[0] = hist_x_[hist_n_ - 1];
    hist_y_[0] = hist_y_[hist_n_ - 1];
    hist_phi_[0] = hist_phi_[hist_n_ - 1];
    hist_n_ = 1;
    hist_from_search_ = false;
  }
  push(x, y, phi);
  x_ = x;
  y_ = y;
  phi_ = phi;
  last_angle_ = {true, phi};
  have_prev_ = true;
  predict();
}

void MotionModel::push(double x, double y, double phi) noexcept {
  if (hist_n_ > 0) phi = hist_phi_[hist_n_ - 1] + rt::wrap_deg(phi - hist_phi_[hist_n_ - 1]);  // unwrapped along the row
  // A search's pose leaves the row once two ROI poses follow it (its interval spans the scan).
  const bool drop_search = hist_from_search_ && hist_n_ >= 2;
  const int drop = (hist_n_ == kMaxRatePoses || drop_search) ? 1 : 0;
  if (drop) {
    for (int i = 1; i < hist_n_; ++i) {
      hist_x_[i - 1] = hist_x_[i];
      hist_y_[i - 1] = hist_y_[i];
      hist_phi_[i - 1] = hist_phi_[i];
    }
    --hist_n_;
    if (drop_search) hist_from_search_ = false;
  }
  hist_x_[hist_n_] = x;
  hist_y_[hist_n_] = y;
  hist_phi_[hist_n_] = phi;
  ++hist_n_;
}

void MotionModel::coast() noexcept {
  // The prediction stands in for the pose (it lies on the fitted line: the rate is kept).
  x_ = pred_x_;
  y_ = pred_y_;
  phi_ = pred_phi_;
  if (have_prev_) push(x_, y_, phi_);
  predict();
}

void MotionModel::hold() noexcept {
  // The last accepted pose only: no velocity until two poses in a row follow.
  if (hist_n_ > 0) {
    hist_x_[0] = hist_x_[hist_n_ - 1];
    hist_y_[0] = hist_y_[hist_n_ - 1];
    hist_phi_[0] = hist_phi_[hist_n_ - 1];
    hist_n_ = 1;
  }
  hist_from_search_ = false;
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
  hist_n_ = 0;
  hist_from_search_ = false;
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
  // The two-pose prediction (the pose noise's and the innovation's reference, see accept()).
  if (predict_velocity_ && have_velocity_ && hist_n_ >= 2) {
    cv_x_ = 2.0 * hist_x_[hist_n_ - 1] - hist_x_[hist_n_ - 2];
    cv_y_ = 2.0 * hist_y_[hist_n_ - 1] - hist_y_[hist_n_ - 2];
    cv_phi_ = rt::wrap_deg(2.0 * hist_phi_[hist_n_ - 1] - hist_phi_[hist_n_ - 2]);
  } else {
    cv_x_ = x_;
    cv_y_ = y_;
    cv_phi_ = rt::wrap_deg(phi_);
  }
  // The least-squares line through the last n poses (t = 0..n−1), evaluated at t = n: weights
  // w_i = 1/n + (t_i − t̄)(n − t̄)/Σ(t − t̄)², Σ w = 1 (n = 2: −1, 2).
  const int n = predict_velocity_ && have_velocity_ ? std::min(hist_n_, rate_poses_) : 0;
  if (n < 2) {
    pred_x_ = x_;
    pred_y_ = y_;
    pred_phi_ = rt::wrap_deg(phi_);
    pred_var_share_ = 1.0;
    return;
  }
  const int first = hist_n_ - n;
  const double tbar = 0.5 * (n - 1);
  double sxx = 0;
  for (int i = 0; i < n; ++i) sxx += (i - tbar) * (i - tbar);
  double px = 0, py = 0, pphi = 0, q = 0;
  for (int i = 0; i < n; ++i) {
    const double w = 1.0 / n + (i - tbar) * (n - tbar) / sxx;
    px += w * hist_x_[first + i];
    py += w * hist_y_[first + i];
    pphi += w * hist_phi_[first + i];
    q += w * w;
  }
  pred_x_ = px;
  pred_y_ = py;
  pred_phi_ = rt::wrap_deg(pphi);
  pred_var_share_ = q;
}

bool MotionModel::surprising(double x, double y, double phi, double wider) const noexcept {
  const double dpos = std::hypot(x - pred_x_, y - pred_y_);
  const double dphi = std::fabs(rt::wrap_deg(phi - pred_phi_));
  const bool known = have_velocity_ && have_innov_;
  const double lim_px = wider * std::max(kSurpriseFloorPx, known ? kSurpriseSigmas * std::sqrt(innov_px2_) : 0.0);
  const double lim_deg = wider * std::max(kSurpriseFloorDeg, known ? kSurpriseSigmas * std::sqrt(innov_deg2_) : 0.0);
  return dpos > lim_px || dphi > lim_deg;
}

double MotionModel::innovation_deg(double phi) const noexcept { return std::fabs(rt::wrap_deg(phi - cv_phi_)); }

MotionModel::ErrorGivenInnovation MotionModel::error_given_innovation(double d, double dphi, double sigma_m_px,
                                                                   double sigma_m_deg) const noexcept {
  const double pred_share = predict_velocity_ ? 5.0 : 1.0;  // the two-pose prediction's σp² over the stream's σ²
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
