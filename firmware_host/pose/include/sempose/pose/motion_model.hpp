// Where the target will be next: constant velocity in x, y and φ from the last two accepted
// poses (or the last pose when tracker.predict_velocity is off), and the ROI centred on that
// prediction, clamped to the field. Also keeps the last tracked angle across a loss (the
// start search's prior). RT, no allocation.
#pragma once

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
  // The target is lost: no velocity, no previous pose (the prediction and the angle prior stay).
  void reset() noexcept;

  double x_px() const noexcept { return x_; }
  double y_px() const noexcept { return y_; }
  double phi_deg() const noexcept { return phi_; }
  double predicted_x_px() const noexcept { return pred_x_; }
  double predicted_y_px() const noexcept { return pred_y_; }
  double predicted_phi_deg() const noexcept { return pred_phi_; }
  const AnglePrior& last_angle() const noexcept { return last_angle_; }

  // A roi_w×roi_h window centred on the prediction, inside a field_w×field_h field.
  Roi window_at_prediction(int roi_w, int roi_h, int field_w, int field_h) const noexcept;
  // The prediction lies outside the field.
  bool prediction_outside(int field_w, int field_h) const noexcept;

 private:
  void predict() noexcept;

  bool predict_velocity_;
  bool have_prev_ = false;
  double x_ = 0, y_ = 0, phi_ = 0;
  double vx_ = 0, vy_ = 0, vphi_ = 0;
  double pred_x_ = 0, pred_y_ = 0, pred_phi_ = 0;
  AnglePrior last_angle_;
};

}  // namespace sempose::pose
