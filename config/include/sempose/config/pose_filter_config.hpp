// Settings of the optional temporal pose filter (firmware_host/pose PoseFilter), read from the
// `tracker.filter:` mapping. Per axis (x, y, φ) a constant-acceleration Kalman filter whose
// process noise is white jerk; an innovation gate re-initialises it from the measurement when
// the motion breaks the model (a bounce, a jump, a torn frame).
#pragma once

namespace sempose::config {

class Section;

struct PoseFilterConfig {
  bool enabled = false;  // false: poses pass through unchanged
  // One-frame measurement noise (1σ) of the pose estimate; ≈ the Cramér–Rao bound at dose 6
  // (192² ROI, 128² pattern). Set it to the noise of the lowest dose in use: too low a value
  // makes the gate fire on ordinary noise and the filter falls back to raw poses.
  double meas_sigma_px = 0.2;
  double meas_sigma_deg = 0.4;
  // Jerk the motion model allows (1σ of a jerk held over a 10 ms frame; internally the
  // continuous white-jerk density q = jerk² · 10 ms, so any frame interval is handled
  // exactly). Larger: less lag on fast-changing motion, less noise reduction.
  double jerk_px_s3 = 1000.0;
  double jerk_deg_s3 = 1000.0;
  // Motion faster than the jerk setting makes the filter lag: its normalized innovations grow
  // (squared, averaged over ~10 frames: NIS > 2). true: that axis' process noise is then
  // raised (×1.5 per frame, up to jerk ×100) and decays back (×0.98 per frame) once the
  // innovations fit again, so the output is never much worse than the raw poses. Costs
  // smoothing when meas_sigma_* is set below the real noise (NIS > 2 on noise alone).
  bool adapt_jerk = true;
  // Normalized innovation |z - prediction| / σ_innovation above this on any axis = the model
  // is broken: re-initialise from the measurement instead of smoothing it away.
  double gate_sigma = 4.5;
  // Frame interval above this (or ≤ 0) = the filter restarts from the measurement.
  double max_gap_s = 0.1;
};

// Reads a `filter:` mapping (the tracker calls it for `tracker.filter`);
// config/src/pose_filter_section.cpp.
void read_pose_filter(Section& section, PoseFilterConfig& out);

}  // namespace sempose::config
