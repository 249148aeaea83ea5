// Tracker state and the reasons a target is lost (README: Conventions: TRACKING, ACQUIRING, LOST
// and why). Shared by pose estimation, the pipeline and the wire protocol mapping.
#pragma once

#include <cstdint>

namespace sempose::pose {

enum class TrackState : std::uint8_t {
  kTracking = 0,
  kAcquiring = 1,  // full-field search running / not found yet
  kLost = 2,       // was tracking, lost it this frame; a full-field search follows
  // Followed (the ROI stays on it) but this pose is not to be trusted: the pose noise the
  // stream itself shows, or the pose's own σ, make it more than 3 px / 10° off with a
  // probability above tracker.max_false_probability, or the target is one of two peaks 180°
  // apart that this dose cannot yet tell apart. Never a pose to drive a robot with.
  kUncertain = 3,
};

// Bit set of why a pose is not trusted (0 while TRACKING normally).
enum LostReason : std::uint8_t {
  kReasonNone = 0,
  kReasonLowScore = 1u << 0,      // ZNCC peak below the threshold for K frames
  kReasonLowPsr = 1u << 1,        // weak peak-to-sidelobe ratio for K frames
  kReasonFlatFrame = 1u << 2,     // blank / saturated / constant ROI
  kReasonOutOfField = 1u << 3,    // predicted pose left the scan field
  kReasonBadFrame = 1u << 4,      // the scan source flagged the frame
  kReasonCommanded = 1u << 5,     // re-acquire requested by the controller
  kReasonAngleUnsettled = 1u << 6, // the walk did not settle: its per-frame angle bound, or its place on the ROI's edge
  kReasonUnexplained = 1u << 7     // the pattern leaves more of the window unexplained than noise
                                   // does (wrong scale, look-alike, torn frame), or than it leaves
                                   // of this target at its own fit level: not the target
};

constexpr const char* to_string(TrackState s) noexcept {
  switch (s) {
    case TrackState::kTracking: return "TRACKING";
    case TrackState::kAcquiring: return "ACQUIRING";
    case TrackState::kLost: return "LOST";
    case TrackState::kUncertain: return "UNCERTAIN";
  }
  return "?";
}

}  // namespace sempose::pose
