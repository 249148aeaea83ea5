// When is a measurement not the target, and when is the target lost: the state decision of
// one frame. A weak measurement (low exact score, far below the target's recent scores, or a
// weak peak-to-sidelobe ratio) is reported with its reasons; K weak frames in a row lose the
// target (a full-field search follows). RT, no allocation.
#pragma once

#include <cstdint>

#include "sempose/config/tracker_config.hpp"
#include "sempose/pose/measurement.hpp"

namespace sempose::pose {

enum class FrameVerdict {
  kAccept,  // TRACKING, the measurement is the target
  kCoast,   // weak, not yet lost: report with its reasons, coast on the motion model
  kLost,    // weak for lost_after_frames frames
};

class LossPolicy {
 public:
  explicit LossPolicy(const config::TrackerConfig& cfg) noexcept : cfg_(cfg) {}

  bool weak(const Measurement& m) const noexcept;
  // kReasonLowScore / kReasonLowPsr bits of a weak measurement.
  std::uint8_t weak_reasons(const Measurement& m) const noexcept;

  // A tracked frame's verdict (counts weak frames).
  FrameVerdict judge(const Measurement& m) noexcept;
  // A start search's result is the target when valid and not weak.
  bool found(const Measurement& m) const noexcept { return m.valid && !weak(m); }

  // The reported score of an accepted pose (the recent mean the relative threshold uses).
  void accepted(float score) noexcept;
  // The target is lost: forget the recent scores and the weak-frame count.
  void reset() noexcept;

 private:
  // A score far below the target's recent scores is a look-alike, not the target (after a
  // jump the old ROI still holds texture that can beat the absolute threshold).
  bool below_recent(const Measurement& m) const noexcept;

  const config::TrackerConfig& cfg_;
  int weak_frames_ = 0;
  double score_mean_ = 0;  // running mean of accepted scores
  bool have_score_mean_ = false;
};

}  // namespace sempose::pose
