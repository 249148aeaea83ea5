#include "sempose/config/pose_filter_config.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {

// Lower bounds are small positives, not 0: every one of these divides or scales a variance.
void read_pose_filter(Section& s, PoseFilterConfig& c) {
  s.opt("enabled", c.enabled);
  s.opt("meas_sigma_px", c.meas_sigma_px, 1e-4, 100.0);
  s.opt("meas_sigma_deg", c.meas_sigma_deg, 1e-4, 180.0);
  s.opt("jerk_px_s3", c.jerk_px_s3, 1e-3, 1e9);
  s.opt("jerk_deg_s3", c.jerk_deg_s3, 1e-3, 1e9);
  s.opt("adapt_jerk", c.adapt_jerk);
  s.opt("gate_sigma", c.gate_sigma, 1.0, 1000.0);
  s.opt("max_gap_s", c.max_gap_s, 1e-4, 60.0);
}

}  // namespace sempose::config
