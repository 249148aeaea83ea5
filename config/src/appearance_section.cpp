#include "sempose/config/appearance_config.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {

void read_appearance(Section& s, AppearanceConfig& c) {
  s.opt("enabled", c.enabled);
  s.opt("frames_per_update", c.frames_per_update, 4, 100000);
  s.opt("min_score", c.min_score, 0.0, 1.0);
  // Below 1.2 ordinary noise alone (16-sample blocks, 16 frames) would empty the support.
  s.opt("outlier_ratio", c.outlier_ratio, 1.2, 1000.0);
  s.opt("block_px", c.block_px, 1, 32);
  s.opt("pose_jitter_px", c.pose_jitter_px, 0.0, 10.0);
  s.opt("angle_jitter_deg", c.angle_jitter_deg, 0.0, 30.0);
  s.opt("min_consistency", c.min_consistency, 0.0, 1.0);
  s.opt("max_drift_px", c.max_drift_px, 0.05, 8.0);
  s.opt("min_support_fraction", c.min_support_fraction, 0.05, 1.0);
  s.opt("refine_template", c.refine_template);
  // 1 would let the recorded pattern drop out entirely (nothing anchors the pose frame).
  s.opt("refine_max_weight", c.refine_max_weight, 0.0, 0.99);
  s.opt("refine_min_motion_px", c.refine_min_motion_px, 0.0, 100.0);
  s.opt("max_drift_deg", c.max_drift_deg, 0.05, 30.0);
}

}  // namespace sempose::config
