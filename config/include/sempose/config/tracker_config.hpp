// Settings of pose estimation (the `tracker:` section) and of the tracked targets (the
// `targets:` list with one pattern set per magnification step). Plain structs with defaults.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sempose/config/appearance_config.hpp"
#include "sempose/config/refine_config.hpp"
#include "sempose/config/pose_filter_config.hpp"

namespace sempose::config {

class Section;

struct TrackerConfig {
  // Correlation geometry.
  std::int32_t pattern_size_px = 128;  // square pattern side of simulated patterns (a pattern file is used at its own size)
  std::int32_t roi_size_px = 192;      // square tracking ROI side (>= pattern_size_px)
  double angle_step_deg = 1.0;         // pattern bank step: 360/step rotated copies
  bool circular_mask = true;           // mask the pattern to its inscribed circle (corners don't bias)
  // A pattern set's shape mask (targets[].pattern_sets[].mask) grown by this many px before
  // use (for a mask drawn tight inside the outline). 0 measured best on the simulated needle
  // and lamella: the prefilter already carries the outline's gradient into the mask's edge
  // pixels, and every px of ring lets static clutter back in.
  double shape_mask_margin_px = 0.0;
  // 5-tap binomial low-pass passes on frame and pattern before correlating (matched filter
  // against shot noise at a few electrons per pixel); 0 = raw pixels.
  std::int32_t prefilter_passes = 1;
  // Orientation walk (paper): correlate j and j±1, move to the best, until the centre wins.
  std::int32_t max_angle_steps_per_frame = 8;
  // In-ROI recovery when the walk hits its bound or the score collapses: FFT correlations
  // at predicted ± sweep window, every sweep step (bounded cost), before declaring LOST.
  double recover_sweep_deg = 30.0;
  double recover_step_deg = 5.0;
  // Loss detection.
  double score_threshold = 0.25;  // ZNCC peak below this = weak frame
  double psr_threshold = 0.0;     // peak-to-sidelobe ratio below this = weak frame (0 = off)
  // Score below this fraction of the running mean of recent accepted scores = weak frame
  // (0 = off): after a jump a look-alike in the old ROI can pass the absolute threshold.
  double relative_score_threshold = 0.7;
  // A tracked pose is weak when its score is below this × the score the noise model says the
  // target attains in that window (0 = off): the pattern explains too little of the window's
  // signal — jaws moving under a rigid pattern, a look-alike, a torn frame (kReasonUnexplained).
  // 0.65 removed every false jaws pose but cost the procedural lamella's recovery after a jump
  // at 2.5 e-/px (pose_accuracy_bench); 0.6 keeps it and leaves 1-3 per jaws row.
  double explained_threshold = 0.6;
  std::int32_t lost_after_frames = 1;  // K consecutive weak frames -> LOST, full-field search
  // A followed pose is reported TRACKING only when the chance that it is more than 3 px or 10°
  // off (issue 13's false-pose rule), from its own σ and from the pose noise the stream shows
  // (MotionModel::pose_noise_*), is at most this; otherwise UNCERTAIN (0 = off). 0.01: the
  // rule's own bound at 1 e-/px.
  double max_false_probability = 0.01;
  // The detector chain's time constant (a first-order low-pass along each scanned line): an
  // edge lags exp(-d/τ)/(1 - exp(-d/τ)) px behind at pixel dwell d (τ 120 ns: 0.77 px at 100 ns,
  // 0.14 px at 250 ns, ~0 at 2 µs). A pose measured at one dwell against a pattern recorded at
  // another is shifted along the line by the difference; with τ known it is taken out, so the
  // governor's dwell changes do not move the pose. 0: no correction (a sim source: the
  // simulated detector's sim.detector_tau_ns, as a calibration would measure it).
  double detector_tau_ns = 0;
  // With detector_tau_ns 0: measure τ from the frames themselves (the noise's correlation along
  // the lines, line_correlation.hpp) and take the lag out as if told; false: no correction. A
  // frame whose noise does not dominate its structure (noise-free, very high dose) is not read;
  // a pattern set without dwell_ns counts the lag its own noise shows (README). With
  // detector_tau_ns given, the same readings check it: a pattern set whose own noise disagrees
  // with the lag its dwell_ns implies counts its measured lag instead (a setup warning); frames
  // whose readings disagree with τ at their dwell are reported (Tracker::detector_tau_status()).
  bool measure_detector_tau = true;
  // A raster scan's rows follow one another in time: a target moving during the scan shows
  // sheared and stretched, and the rigid fit reads part of that as a turn (0.3° at 200 px/s with
  // 50 µs rows). true: the bias the tracked velocity causes (scan_motion.hpp) is taken out of
  // the reported pose, after the rules judged the measured one (taken out before them,
  // pose_envelope_probe reported more false TRACKING poses; pose README: Motion during the scan).
  // false for a scan whose rows do not run top to bottom in time.
  bool correct_scan_motion = true;
  // Start search (full field): box pyramid, coarse angles, best candidates refined.
  std::int32_t search_downsample = 8;
  double search_angle_step_deg = 20.0;
  std::int32_t search_candidates = 4;
  double search_refine_window_deg = 12.0;  // ± around a candidate's coarse angle
  double search_refine_step_deg = 4.0;     // FFT correlations inside that window, then the walk
  // Scales the start search for a new target covers when no SELECT gave the microscope's
  // nm/px, as factors of the expected scale (the pattern's own size, or a SELECT's): levels
  // 25 % apart that reach min and max (default: 0.8, 1, 1.25, each good for ±12 %; min = max
  // = 1: the expected scale only). A scale away from the expected one wins only on clear
  // evidence; after a loss the search is narrow around the last tracked scale.
  double search_scale_min = 0.75;
  double search_scale_max = 1.33;
  // Motion model and sub-pixel.
  bool predict_velocity = true;            // constant-velocity prediction of x, y and phi
  // The velocity is the least-squares line through this many last poses in a row (2: the last
  // two poses' difference, which doubles one pose's error into the next prediction; 3: the
  // newest pose weighs 4/3). 2 by default: with 3, pose_false_tracking_test's warped jump at
  // 1 e-/px had a false TRACKING pose (README: Known limitations).
  std::int32_t predict_rate_poses = 2;
  // The attainable score × the recorded pattern's own √(S/(S+N)) (its noise as PatternBank
  // measures it for σ), and the target's level at a search frame capped at that attainable score.
  // Off: on, the explained check passed a wander on --full (procedural lamella jump at 2.5
  // e-/px, frame 81, 3.4 px off) that it refuses off (README: Known limitations).
  bool attainable_pattern_noise = false;
  // Sub-pixel / sub-step: one joint quadratic fit in (x, y, φ) over 19 exact scores around
  // the best grid point, on log scores (gaussian) or scores (quadratic).
  std::string subpixel = "gaussian";       // gaussian | quadratic
  // σ per tracked pose (pose_uncertainty.hpp): the side of the tiles the sandwich covariance
  // sums the residual's scores over (px; the residual is correlated within a tile). The factors
  // were fitted on needle_tip and lamella_post rows of pose_accuracy_bench only
  // (tests/pose/fit_sigma_calibration.py --pooled --k 0.75, with the pattern-noise term; README: Uncertainty):
  //   σ² = calibration²·(sandwich + walk step²) + noise_factor²·(Fisher × residual variance) + floor²
  // and σφ's first two parts × angle_factor, σscale × scale_factor (fitted after the others, the
  // same way: fit_sigma_calibration.py --pooled prints it).
  std::int32_t sigma_tile_px = 8;
  double sigma_calibration = 0.75;
  double sigma_noise_factor = 4.95;
  double sigma_angle_factor = 1.18;
  double sigma_scale_factor = 0.92;
  // A floor added in quadrature to σx, σy (px of the loaded ROI) and σφ (deg): a bias of the
  // pattern against the target that no single frame shows (0: the fit chose none).
  double sigma_floor_px = 0.0, sigma_floor_deg = 0.0;
  // Model the recorded pattern's own noise (measured on the pattern at setup): its gradients
  // are taken out of JᵀJ, so σ grows with a noisy pattern (README: Uncertainty).
  bool sigma_pattern_noise = true;
  // Fit on Σtf/√(var − noise var) rather than the ZNCC, noise var estimated at the best
  // match: removes the pull of noisy windows towards more signal/noise variance.
  bool fit_noise_correction = true;
  // Score the fit's samples with a brightness ramp across the window (the background plane) as
  // nuisance where it is significant: takes the pull of charging gradients off the pose. Off:
  // measured, another object crossing the window then drew the pose onto it (pose README).
  bool fit_background_plane = false;
  // Optional temporal filter of the reported pose (tracker.filter:); the ROI placement keeps
  // using the raw measurements, so the filter cannot feed back into tracking.
  PoseFilterConfig filter;
  // Learned appearance (tracker.appearance:): pixels the target does not explain leave the
  // exact scorer's support.
  AppearanceConfig appearance;
  // Final Gauss–Newton fit at the refinement seam (tracker.refine:).
  RefineConfig refine;
};

struct PatternSetConfig {
  std::string file;            // PGM of the pattern at this magnification step
  double nm_per_px = 1.0;      // scale of this magnification step
  std::string mask;            // optional PGM, pattern-sized: non-zero = the target's own pixels
  std::uint32_t dwell_ns = 0;  // pixel dwell the pattern was recorded at (0: lag-free, e.g. a long dwell)
  bool nm_per_px_given = false;  // from the config (else 1: CAN carries pixels; run says so)
};

struct TargetConfig {
  std::string name;
  std::vector<PatternSetConfig> pattern_sets;  // index = magnification step
  // Where the target is at start: [x_px, y_px, radius_px] in field pixels (empty: anywhere). The
  // start searches keep to this circle until the target is first TRACKING. A copy of the object
  // elsewhere in the field (a twin, the background a target was cut from) scores as well as the
  // target itself; only its place tells them apart (README Known limitations).
  std::vector<double> start_area;
};

// A rule between settings that is broken: the key to blame and why (empty key: none).
struct SettingProblem {
  std::string key;
  std::string message;
  explicit operator bool() const noexcept { return !key.empty(); }
};

// The tracker settings' rules that depend on the pattern's side: the config reader checks them
// with pattern_size_px, Tracker::create with the side of the pattern actually given. One
// implementation, so the two can never disagree.
SettingProblem check_tracker_sizes(const TrackerConfig& c, int pattern_px);

// Reads the `tracker:` mapping (section may be absent: defaults stay). Errors go to the
// section's Errors (file:line, key, value, allowed range).
void read_tracker(Section& tracker, TrackerConfig& out);

// Reads `targets:` from the top-level section:
//   targets:
//     - name: gripper
//       pattern_sets: [ {file: gripper_x1000.pgm, nm_per_px: 40}, {file: ..., nm_per_px: 10} ]
// Relative file names stay as written (the caller resolves them against the config's folder).
void read_targets(Section& root, std::vector<TargetConfig>& out);

}  // namespace sempose::config
