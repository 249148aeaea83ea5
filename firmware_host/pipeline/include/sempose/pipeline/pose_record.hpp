// The one place a tracker's estimate becomes the PoseRecord that leaves for the sinks, so the
// RT pipeline and the offline runner (replay) write the same record for the same frame.
#pragma once

#include <cstdint>

#include "sempose/hal/frame.hpp"
#include "sempose/pipeline/pose_sink.hpp"
#include "sempose/pose/tracker.hpp"

namespace sempose::pipeline {

// m: the frame the pose came from (its t_pose_done_ns already set); nm_per_px: the active
// magnification step's scale. RT-safe.
inline PoseRecord make_pose_record(const hal::FrameMeta& m, const pose::PoseEstimate& est, std::uint8_t target,
                                   std::uint32_t pose_seq, double nm_per_px) noexcept {
  PoseRecord p;
  p.frame_seq = m.seq;
  p.pose_seq = pose_seq;
  p.target = target;
  p.pattern_set = est.pattern_set;
  p.state = est.state;
  p.reason_bits = est.reason_bits;
  p.look_alike = est.look_alike;
  p.angle_order = est.angle_order;
  p.x_px = est.x_px;
  p.y_px = est.y_px;
  p.phi_deg = est.phi_deg;
  p.score = est.score;
  p.psr = est.psr;
  p.target_scale = est.scale;
  p.sigma_x_px = est.sigma_x_px;
  p.sigma_y_px = est.sigma_y_px;
  p.sigma_phi_deg = est.sigma_phi_deg;
  p.sigma_scale = est.sigma_scale;
  p.dwell_ns = m.dwell_ns;
  p.nm_per_px = nm_per_px;
  p.t_scan_end_ns = m.t_scan_end_ns;
  p.t_beam_ns = est.t_beam_ns != 0 ? est.t_beam_ns : m.t_scan_end_ns;
  p.t_pose_done_ns = m.t_pose_done_ns;
  if (target < m.truth_count && m.truth[target].present) {
    p.truth_present = true;
    p.truth_x_px = m.truth[target].x_px;
    p.truth_y_px = m.truth[target].y_px;
    p.truth_phi_deg = m.truth[target].phi_deg;
  }
  return p;
}

}  // namespace sempose::pipeline
