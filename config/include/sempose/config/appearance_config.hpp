// Settings of learned appearance (the `tracker.appearance:` mapping; firmware_host/pose
// appearance_observer / appearance_model). From the frames it tracks well, the tracker learns
// which pixels of the pattern the target explains: pixels whose value is not the pattern's as
// the target moves (background under the pattern's rim, a gripper's moving jaws) leave the
// exact scorer's support, so they stop pulling the pose. A user's shape mask stays a prior
// (the learned support is always inside it).
#pragma once

#include <cstdint>

namespace sempose::config {

class Section;

struct AppearanceConfig {
  bool enabled = false;
  // Good frames (TRACKING, no weak reason, score >= min_score) summed per update of the
  // support; the statistics of every accepted update accumulate (the support sharpens as
  // the target moves over more background).
  std::int32_t frames_per_update = 16;
  double min_score = 0.3;
  // A pixel leaves the support when its mean squared residual against the recorded pattern
  // (gain and offset fitted per frame) exceeds this many times what the detector noise and
  // the pose's own jitter explain. Decided per block_px² block of the pattern (the block's
  // statistics: 16 px for 4², so a 16-frame update separates a 2× excess from noise).
  double outlier_ratio = 2.0;
  std::int32_t block_px = 4;
  // Pose jitter (1σ) the test allows for: a pixel on a steep edge has a residual of its
  // gradient times the pose error without being background; the angle's share grows with the
  // distance from the centre (0.5° is 0.5 px at the rim of a 128² pattern), without it the
  // target's outer edges, which carry the angle, would be dropped.
  double pose_jitter_px = 0.3;
  double angle_jitter_deg = 0.5;
  // Drift check (Matthews–Ishikawa–Baker): the mean of the aligned observations, over the new
  // support, must match the recorded pattern with ZNCC >= min_consistency and lie within
  // max_drift_px of it; and the support must keep min_support_fraction of the pattern circle.
  double min_consistency = 0.6;
  double max_drift_px = 1.0;
  double min_support_fraction = 0.25;
  // Refined template (Matthews–Ishikawa–Baker's template update with drift correction): each
  // accepted batch's mean aligned observation is aligned to the recorded pattern over the
  // learned support (sub-pixel shift and sub-degree angle, Gauss–Newton), corrected by that
  // warp, refused when the correction exceeds max_drift_px / max_drift_deg, and averaged into
  // a running mean; the bank's copies are rebuilt from the recorded pattern blended with it,
  // per pixel by the two noise variances (minimum variance), the observations' weight capped
  // at refine_max_weight (the recorded pattern always keeps the rest: the pose frame's
  // anchor). A batch whose poses spread less than refine_min_motion_px across the background
  // (RMS of the field positions, plus the angle's RMS × the circle's radius) does not enter
  // the template: a target standing still would freeze its background into the rim.
  bool refine_template = false;
  double refine_max_weight = 0.9;
  double refine_min_motion_px = 2.0;
  double max_drift_deg = 1.0;
};

// Reads a `appearance:` mapping (tracker.appearance); config/src/appearance_section.cpp.
void read_appearance(Section& section, AppearanceConfig& out);

}  // namespace sempose::config
