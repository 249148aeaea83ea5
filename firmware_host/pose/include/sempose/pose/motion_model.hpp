// Where the target will be next: constant velocity in x, y and φ from the last two accepted
// poses (or the last pose when tracker.predict_velocity is off), and the ROI centred on that
// prediction, clamped to the field. Also keeps the last tracked angle across a loss (the
// start search's prior). It also learns how far accepted poses land from their prediction
// (the innovations), so a pose that lands much farther than the motion seen so far can be
// told apart (surprising()). RT, no allocation.
#pragma once

#include <algorithm>
#include <cmath>

#include "sempose/pose/pose_frame.hpp"
#include "sempose/pose/start_search.hpp"

namespace sempose::pose {

class MotionModel {
 public:
  explicit MotionModel(bool predict_velocity) noexcept : predict_velocity_(predict_velocity) {}

  // An accepted pose; fresh: the first after a search (no velocity from it).
  void accept(double x_px, double y_px, double phi_deg, bool fresh) noexcept;
  // A weak frame that is not yet a loss: the prediction stands in for the pose.
  void coast() noexcept;
  // The target is there but its pose is not trusted (held): the prediction stays at the last
  // accepted pose, without velocity, so the ROI does not wander after what it cannot vouch for.
  void hold() noexcept;
  // The target is lost: no velocity, no previous pose (the prediction and the angle prior stay).
  void reset() noexcept;

  double x_px() const noexcept { return x_; }
  double y_px() const noexcept { return y_; }
  double phi_deg() const noexcept { return phi_; }
  double predicted_x_px() const noexcept { return pred_x_; }
  double predicted_y_px() const noexcept { return pred_y_; }
  double predicted_phi_deg() const noexcept { return pred_phi_; }
  const AnglePrior& last_angle() const noexcept { return last_angle_; }

  // The pose lands farther from the prediction than the motion seen so far makes plausible:
  // beyond kSurpriseSigmas × the RMS innovation of the accepted frames (with floors for a
  // target that moved exactly as predicted so far), in position or in angle. Without a
  // velocity (the first frame after a search) the prediction is the last pose and any move
  // beyond the floors is a surprise: nothing was seen yet that would vouch for it.
  // wider > 1 scales the sigmas and the floors (a graver surprise).
  bool surprising(double x_px, double y_px, double phi_deg, double wider = 1.0) const noexcept;
  // RMS of the innovations (accepted pose − its prediction), 0 before any.
  double innovation_rms_px() const noexcept { return std::sqrt(innov_px2_); }
  double innovation_rms_deg() const noexcept { return std::sqrt(innov_deg2_); }
  bool has_velocity() const noexcept { return have_velocity_; }
  // The motion since the last search is known: a velocity and at least two innovations of
  // predictions made from ROI frames only (the velocity right after a search spans the long
  // full-field scan and overshoots once).
  bool motion_known() const noexcept { return have_velocity_ && innovations_since_fresh_ >= 2; }

  // An upper bound of the accepted poses' error SD per axis (px) and in angle (deg), as the
  // stream itself shows it: for a constant-velocity prediction the innovation is
  // e_k − 2e_{k−1} + e_{k−2} + the target's acceleration, so with pose errors of SD σ per
  // axis E[|d|²] = 12σ² + |a|² (two axes; angle 6σ² + a²; without velocity prediction a
  // first difference: 4σ², 2σ²). Unlike a pose's own σ (the fit's local curvature), this sees
  // poses that wander to a neighbouring maximum for a frame or several (at 1 e-/px the
  // lamellae's poses leave the truth by 3-8 px for 1-4 frames at the target's score). An
  // acceleration only raises it (no pose is trusted more for it). Taking out the acceleration
  // by the lag-1 product of the innovations was tried: a wander over several frames is
  // correlated like an acceleration and cancelled too. Known after two such innovations.
  // Two memories, the larger counts: ~5 frames (a wander now) and ~20 frames (the level of
  // this target at this dose: a single-frame excursion of 3-4 px at 1 e-/px starts like a
  // smooth move, so the short memory alone sees it only once it is over).
  bool pose_noise_known() const noexcept { return have_noise_ && innovations_since_fresh_ >= 3; }
  double pose_noise_px() const noexcept {
    return std::sqrt(std::max(noise_px2_, level_px2_) / (predict_velocity_ ? 12.0 : 4.0));
  }
  double pose_noise_deg() const noexcept {
    return std::sqrt(std::max(noise_deg2_, level_deg2_) / (predict_velocity_ ? 6.0 : 2.0));
  }
  static constexpr double kLevelShare = 0.05;

  static constexpr double kSurpriseSigmas = 4.0;
  // Floors: an innovation this small is never a surprise (measurement noise at 1 e⁻/px is
  // ~0.5 px / 1° per frame, a constant-velocity prediction from two of them ~2.5× that).
  static constexpr double kSurpriseFloorPx = 2.0, kSurpriseFloorDeg = 4.0;

  // A roi_w×roi_h window centred on the prediction, inside a field_w×field_h field.
  Roi window_at_prediction(int roi_w, int roi_h, int field_w, int field_h) const noexcept;
  // The prediction lies outside the field.
  bool prediction_outside(int field_w, int field_h) const noexcept;

 private:
  void predict() noexcept;

  bool predict_velocity_;
  bool have_prev_ = false;
  bool have_velocity_ = false;  // the prediction is the model's full one (velocity from two poses in a row)
  // Running mean squares of the innovations of frames predicted with a velocity. Kept across
  // a loss: how irregularly the target moves is a property of the target and its drive.
  double innov_px2_ = 0, innov_deg2_ = 0;
  bool have_innov_ = false;
  int innovations_since_fresh_ = 0;
  // Running mean squares of the innovations of predictions made from two ROI poses (the
  // pose-noise bound); kept across a loss like the ones above.
  double noise_px2_ = 0, noise_deg2_ = 0, level_px2_ = 0, level_deg2_ = 0;
  bool have_noise_ = false;
  double x_ = 0, y_ = 0, phi_ = 0;
  double vx_ = 0, vy_ = 0, vphi_ = 0;
  double pred_x_ = 0, pred_y_ = 0, pred_phi_ = 0;
  AnglePrior last_angle_;
};

}  // namespace sempose::pose
