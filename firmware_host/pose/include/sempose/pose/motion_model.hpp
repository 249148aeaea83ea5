// Where the target will be next: constant velocity in x, y and φ, the line fitted (least
// squares) through the last rate_poses accepted poses in a row (tracker.predict_rate_poses; 2:
// the last two poses' difference) and extrapolated one frame (or the last pose when
// tracker.predict_velocity is off), and the ROI centred on that
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
  // rate_poses: how many of the last poses in a row the velocity is fitted over (2..kMaxRatePoses).
  // With two, the prediction is 2·x_k − x_{k−1}: one pose's error is doubled into the next
  // prediction (a pose 3° off predicts 6° short; the walk from there stopped on a neighbouring
  // maximum, README Known limitations). With three (not the default: README, Known limitations) the
  // fitted line's value one frame ahead weighs the poses 4/3, 1/3, −2/3 (newest first; its
  // variance 2.33σ² against 5σ²), with four 1, 0.5, 0, −0.5 (1.5σ²). A longer fit lags a real
  // acceleration longer, so a pose the motion so far does not explain (surprising()) that is
  // accepted breaks the line: the rate restarts from it and the pose before it (a bounce).
  static constexpr int kMaxRatePoses = 8;
  explicit MotionModel(bool predict_velocity, int rate_poses = 2) noexcept
      : predict_velocity_(predict_velocity), rate_poses_(std::clamp(rate_poses, 2, kMaxRatePoses)) {}

  // An accepted pose; fresh: the first after a search (no velocity from it). dwell_ns and
  // score: the pixel dwell of the frame it was measured on (0: not known) and its score, learnt
  // with the pose noise (what the noise was measured at).
  void accept(double x_px, double y_px, double phi_deg, bool fresh, double dwell_ns = 0, double score = 0) noexcept;
  // A weak frame that is not yet a loss: the prediction stands in for the pose.
  void coast() noexcept;
  // The target is there but its pose is not trusted (held): the prediction stays at the last
  // accepted pose, without velocity, so the ROI does not wander after what it cannot vouch for.
  void hold() noexcept;
  // The target is lost: no velocity, no previous pose (the prediction and the angle prior stay).
  // The pose noise learnt so far is carried over (pose_noise_carried()).
  void reset() noexcept;
  // The target's look or scale changed (REACQUIRE, another pattern set or magnification): the
  // pose noise learnt before says nothing about the next stream.
  void forget_noise() noexcept;

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
  // stream itself shows it: for a constant-velocity prediction from two poses the innovation
  // is e_k − 2e_{k−1} + e_{k−2} + the target's acceleration, so with pose errors of SD σ per
  // axis E[|d|²] = 12σ² + |a|² (two axes; angle 6σ² + a²; without velocity prediction a
  // first difference: 4σ², 2σ²). Whatever rate the ROI follows (rate_poses), the pose noise is
  // learnt from the two-pose prediction's innovations, so these figures keep their meaning. Unlike a pose's own σ (the fit's local curvature), this sees
  // poses that wander to a neighbouring maximum for a frame or several (at 1 e-/px the
  // lamellae's poses leave the truth by 3-8 px for 1-4 frames at the target's score). An
  // acceleration only raises it (no pose is trusted more for it). Taking out the acceleration
  // by the lag-1 product of the innovations was tried: a wander over several frames is
  // correlated like an acceleration and cancelled too. Known after two such innovations.
  // Two memories, the larger counts: ~5 frames (a wander now) and ~20 frames (the level of
  // this target at this dose: a single-frame excursion of 3-4 px at 1 e-/px starts like a
  // smooth move, so the short memory alone sees it only once it is over).
  //
  // After a loss of the same target (a jump, a torn frame) the noise learnt before it is
  // carried over (pose_noise_carried()): same target, same detector, so a re-acquired pose is
  // judged against it from its first frame instead of waiting three ROI frames for the new
  // stream's own innovations (that wait made recovery after a jump 5-6 frames instead of 1-2).
  // The caller adapts it to the frame's dwell and score (carried_noise_factor).
  bool pose_noise_known() const noexcept { return have_noise_ && (innovations_since_fresh_ >= 3 || carried_); }
  bool pose_noise_carried() const noexcept { return carried_ && innovations_since_fresh_ < 3; }
  // The pixel dwell and the score the pose noise was learnt at (running means over the same ~20
  // frames as its long memory; 0: not known).
  double pose_noise_dwell_ns() const noexcept { return noise_dwell_ns_; }
  double pose_noise_score() const noexcept { return noise_score_; }
  // How much larger the carried pose noise is on a frame of pixel dwell dwell_ns whose pose
  // scores score (never smaller: the carried noise is a bound, and a longer dwell or a better
  // score only makes it more careful; 0 = not known, no change). A pose's error variance goes
  // as the frame's noise over the target's signal:
  //  * the dwell: detected electrons per pixel ∝ dwell, so the variance ∝ 1/dwell (the
  //    governor shortens the dwell once the compute time allows, and a full-field search frame
  //    is scanned at its own dwell);
  //  * the score: a ZNCC r leaves (1 − r²)/r² of noise per unit of explained signal; a target
  //    re-found over other background, or after the beam drifted, scores lower than its level
  //    before the loss (the procedural lamella after a jump: 0.57-0.61 where it scored ~0.70).
  double carried_noise_factor(double dwell_ns, double score) const noexcept;
  double pose_noise_px() const noexcept {
    return std::sqrt(std::max(noise_px2_, level_px2_) / (predict_velocity_ ? 12.0 : 4.0));
  }
  double pose_noise_deg() const noexcept {
    return std::sqrt(std::max(noise_deg2_, level_deg2_) / (predict_velocity_ ? 6.0 : 2.0));
  }
  static constexpr double kLevelShare = 0.05;

  // A measured pose's error given where it landed against the prediction (Gaussian fusion, as
  // a Kalman update): the measurement's error e (per-axis SD sigma_m) and the prediction's
  // error e_p are independent, the innovation d = e − e_p is seen, so e | d is Gaussian with
  // mean d·σm²/(σm² + σp²) and per-axis variance σm²σp²/(σm² + σp²). σp² is the prediction's:
  // for a constant-velocity prediction from two poses measured as this stream's are,
  // 4σ² + σ² = 5σ² (σ = pose_noise, which holds the target's acceleration too); without
  // velocity prediction σ². The innovation is taken against that two-pose prediction
  // (innovation_px/deg), whatever rate the ROI follows: the rule was calibrated on it. A pose that jumped to a neighbouring maximum lands far from the
  // prediction, and its error given the innovation is centred away from 0: at 1 e⁻/px the
  // first frame of a wander (4 px off, 6 px from the prediction, the stream's noise 0.9 px)
  // has a 3-6 % chance of being > 3 px off given its innovation where its σ alone says 0.4 %.
  // Only meaningful when the prediction was made from two ROI poses (prediction_from_roi_poses()
  // before the pose was accepted).
  struct ErrorGivenInnovation {
    double offset_px = 0, sd_px = 0;    // |mean| of the 2-D position error, per-axis SD
    double offset_deg = 0, sd_deg = 0;  // |mean| of the angle error, its SD
  };
  // d_px, d_deg: the innovation's size (innovation() before the pose is accepted).
  ErrorGivenInnovation error_given_innovation(double d_px, double d_deg, double sigma_m_px, double sigma_m_deg) const noexcept;
  // How far a pose lands from the two-pose prediction (2·x_k − x_{k−1}; the ROI's, when
  // rate_poses is 2), in position and in angle.
  double innovation_px(double x_px, double y_px) const noexcept { return std::hypot(x_px - cv_x_, y_px - cv_y_); }
  double innovation_deg(double phi_deg) const noexcept;
  // The prediction for the next frame is made from two ROI poses (a velocity not spanning a
  // full-field scan) and the stream's pose noise is known.
  bool prediction_from_roi_poses() const noexcept { return have_velocity_ && innovations_since_fresh_ >= 1 && pose_noise_known(); }
  // The current prediction's variance over one pose's, per axis (5 from two poses, 1.5 from four).
  double prediction_variance_share() const noexcept { return pred_var_share_; }

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

  void push(double x, double y, double phi) noexcept;

  bool predict_velocity_;
  int rate_poses_;
  // The accepted (or coasted) poses in a row the velocity is fitted over, oldest first; angles
  // unwrapped along the row. hist_from_search_: the oldest is a search's pose (its interval to
  // the next spans the full-field scan): dropped once two ROI poses follow it.
  double hist_x_[kMaxRatePoses] = {}, hist_y_[kMaxRatePoses] = {}, hist_phi_[kMaxRatePoses] = {};
  int hist_n_ = 0;
  bool hist_from_search_ = false;
  // The current prediction's variance over one pose's (per axis: Σ w² of its weights on the poses).
  double pred_var_share_ = 1.0;
  double cv_x_ = 0, cv_y_ = 0, cv_phi_ = 0;  // the two-pose prediction (pose noise, innovation)
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
  int noise_updates_ = 0;  // innovations learnt into the pose noise since it was last forgotten
  bool carried_ = false;   // the pose noise is from the stream before the last loss
  double noise_dwell_ns_ = 0, noise_score_ = 0;
  double x_ = 0, y_ = 0, phi_ = 0;
  double pred_x_ = 0, pred_y_ = 0, pred_phi_ = 0;
  AnglePrior last_angle_;
};

}  // namespace sempose::pose
