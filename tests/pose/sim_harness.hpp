// Closed-loop tracking on the simulated SEM for tests and benchmarks: the tracker asks for a
// ROI, the simulator renders it at the virtual time of its scan, the tracker updates, the
// pose is compared with the simulator's truth (mid-scan pose). Setup allocates; run() only
// calls the RT methods. The target "warped" is simulator-free: a real SEM image moved rigidly
// to exact poses (warp_scene.hpp), pure Poisson noise. run_peer() runs another tracker (the
// benchmark's ViSP) on the same sequence: the same scene, trajectory and frame times.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sempose/config/sim_config.hpp"
#include "sempose/config/tracker_config.hpp"
#include "sempose/hal/sim_source.hpp"
#include "sempose/pipeline/pose_input.hpp"
#include "sempose/pose/tracker.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"
#include "warp_scene.hpp"

namespace sempose::pose::testing {

struct Scenario {
  std::string motion = "smooth";  // static | smooth | fast | spin | jump
  double dose_e = 6.0;            // detected electrons per pixel at the dwell
  int frames = 200;
  std::uint64_t seed = 1;
  std::int32_t field_w = 640, field_h = 480;
  std::uint32_t dwell_ns = 250;
  double start_phi_deg = 0;
  double start_x_px = 320, start_y_px = 240;
  bool noise = true;
  // needle_tip: the sim's default needle (real SEM, its last 120 px up to the tip at 3/4
  // scale, threshold mask); lamella_post: the lamella's end on its post (real SEM);
  // lamella: the procedural lamella.
  std::string target = "lamella_post";
  bool drift = true;  // the simulator's slow image drift and beam lag
  bool background = true;  // false: a flat background (no static clutter under the pattern)
  // > 0: the procedural background's granular contrast (the simulator's default otherwise):
  // static clutter that fills the recorded pattern as much as the target does, or more.
  double background_contrast = -1;
  double target_brightness = -1;  // > 0: the target's brightness (its texture's default otherwise)
  // motion "step": still while the start search scans the field, then steps by (step_x_px,
  // step_y_px) every step_period_s (the sim's staircase, one step up, one down).
  double step_x_px = 0, step_y_px = 0, step_period_s = 0.1;
  bool shape_mask = false;  // give the tracker the target's shape mask with its pattern (opt-in, see README)
  bool shape_mask_rigid_only = false;  // with shape_mask: only the part rigid with the pose (the gripper's body)
  int pattern_frames = 10;  // frames averaged into the recorded pattern (its own noise: 1/√ of a frame's)
  // Effects (issue 13's hard cases), all off by default:
  double scale_from = 1.0;        // the target's scale ramps from this ...
  double scale_to = 1.0;          // ... to this over the run (equal: a constant scale)
  bool charging_defocus = false;  // gain 1 → 0.65 (±10 % wobble), offset 0 → +0.08, defocus 0 → 1.5 px, detector τ 120 ns
  bool jaws = false;              // target "gripper": each jaw opens and closes (below; 8 px, period 0.4 s)
  double jaws_amplitude_px = 8.0, jaws_period_s = 0.4;
  double jaws_open_px = 0;        // target "gripper": each jaw held this far open (the pattern is recorded closed)
  double detector_tau_ns = 0;     // > 0: the detector's line low-pass alone (250 ns = 1 px at 250 ns dwell)
  std::uint32_t pattern_dwell_ns = 0;  // > 0: the pattern recorded at this dwell (else at the frames' dwell_ns)
  bool tell_detector_tau = true;       // the tracker is told the simulated detector's τ (tracker.detector_tau_ns)
  double told_detector_tau_ns = 0;     // > 0: told this τ instead (a detector swapped since its calibration)
  // The pattern recorded through no low-pass (a clean crop: its set's dwell_ns 0) while the frames
  // go through detector_tau_ns. The warped target's pattern always is; its frames are low-passed
  // along each line here (the tracker is never told τ there).
  bool pattern_lag_free = false;
  // false: the pattern recorded through the detector as above, but its set given without its
  // dwell_ns (a pattern file nobody annotated): the tracker has to tell its lag from its noise.
  bool pattern_dwell_told = true;
  // Approximate frame period (192² ROI at 250 ns + flyback + modelled compute), for ramps over the run.
  double run_s() const { return frames * 0.0101 * (dwell_ns / 250.0); }
  // Faults (the pattern is always recorded from the target as configured above):
  int vanish_after = -1;         // >= 0: the target is gone from this frame on (background only)
  bool target_in_field = true;   // false: the target sits far outside the field from the start
  enum class Frames { kScene, kBlank, kSaturated } frames_kind = Frames::kScene;  // blank/saturated: every pixel 0 / full scale
  // Target "warped" only: on frame kick_frame the target is moved off its trajectory by this
  // much for that frame alone (a pose off the line, as a noisy measurement would be; the truth
  // follows it).
  int kick_frame = -1;
  double kick_x_px = 0, kick_y_px = 0, kick_phi_deg = 0;
  // Cases outside the benchmark's envelope (probe_envelope.cpp, test_false_tracking.cpp),
  // simulator targets only: edit_run changes the scene of the run after the pattern was
  // recorded (a magnification step, a second target, charging, defocus); frame_fault changes
  // each rendered ROI frame (seq = frame index; a beam blanked mid-scan, saturated lines),
  // max_level is full scale.
  std::function<void(config::SimConfig&)> edit_run;
  std::function<void(std::uint64_t seq, const hal::Roi& roi, hal::Pixel* px, hal::Pixel max_level)> frame_fault;
};

// The warped real SEM target: lamella_on_post_eb.pgm seen through a σ 1 px PSF; the pattern is
// the crop centred on scene point (563.5, 527.5) (as the bias table's).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive in std::vector<float>::resize
inline const WarpScene& warped_scene() {
  static const WarpScene s = WarpScene::load(std::string(SEMPOSE_TEST_DATA) + "/sem/lamella_on_post_eb.pgm", 1.0);
  return s;
}
#pragma GCC diagnostic pop
constexpr double kWarpCx = 563.5, kWarpCy = 527.5;

// Dresses a simulated target as one of the benchmark's targets (Scenario::target): texture,
// size and brightness; pose and trajectory are left to the caller. The needle tip is the sim's
// default target (a fresh SimConfig's first); any other name is dressed as it.
inline void dress_as(const std::string& target, config::SimTargetConfig& t) {
  const config::SimTargetConfig needle = config::SimConfig{}.targets[0];
  t.texture = needle.texture;
  t.width_px = needle.width_px;
  t.height_px = needle.height_px;
  t.brightness = needle.brightness;
  if (target == "lamella_post") {
    // The lamella's end on its post (real SEM texture): edges in two directions and surface
    // detail, shown as a 100 px square so the 128 px pattern holds its outline, not a flat interior.
    t.texture = config::TextureConfig{};
    t.texture.path = std::string(SEMPOSE_TEST_DATA) + "/sem/lamella_on_post_eb.pgm";
    t.texture.crop_x = 420;
    t.texture.crop_y = 460;
    t.texture.crop_w = 180;
    t.texture.crop_h = 180;
    t.texture.mask = "full";
    t.width_px = 100;  // scaled down so its edges lie inside the 128 px pattern circle
    t.height_px = 100;
  } else if (target == "lamella") {
    t.texture = config::TextureConfig{};
    t.texture.source = "lamella";
    t.width_px = 100;
    t.height_px = 64;
  } else if (target == "gripper") {
    // The procedural two-jaw gripper (body left, jaws to +x); the pose point is the texture
    // centre, on the body's side of the jaws' roots.
    t.texture = config::TextureConfig{};
    t.texture.source = "gripper";
    t.width_px = 110;
    t.height_px = 84;
    t.brightness = 0.9;
  } else {
    t.texture.path = std::string(SEMPOSE_TEST_DATA) + "/sem/needle_contact_eb.pgm";
  }
}

// Another object, of another pattern, meeting the target: the tool coming to the sample (a needle
// to the lamella, the lamella on post to the needle). The target is still at x 260 while the
// other object comes in from 300 px to its right and slows to rest gap_px from it (a quarter of a
// sine, reached at 80 % of the run, then the start of its way back), or the target moves to the
// still object the same way. The other object is drawn over the target where they overlap
// (pose_envelope_probe other_object_*, pose_false_tracking_test).
inline void meet_other_object(Scenario& s, double gap_px, bool target_moves) {
  s.frames = 120;
  s.start_x_px = 260;
  s.motion = "static";
  const std::string other = s.target == "needle_tip" ? "lamella_post" : "needle_tip";
  const double far_px = 300, reach_s = 0.8 * s.run_s();
  s.edit_run = [=](config::SimConfig& c) {
    config::SimTargetConfig b = c.targets[0];
    dress_as(other, b);
    b.enabled = true;
    b.phi_deg = 0;
    b.x_px = c.targets[0].x_px + far_px;
    b.trajectory = config::TrajectoryConfig{};
    config::TrajectoryConfig approach;
    approach.kind = "sine";
    approach.amplitude_x_px = (target_moves ? 1 : -1) * (far_px - gap_px);
    approach.period_s = 4 * reach_s;
    (target_moves ? c.targets[0].trajectory : b.trajectory) = approach;
    c.targets[1] = b;
  };
}

inline config::SimConfig make_sim_config(const Scenario& s) {
  config::SimConfig c;
  c.seed = s.seed;
  c.clock = "virtual";
  c.noise = s.noise;
  c.yield = 0.1;
  // n = 6.24 · I[pA] · τ[µs] · η  →  I for the requested dose.
  c.beam_current_pa = s.dose_e / (6.24 * (s.dwell_ns * 1e-3) * c.yield);
  c.background.path = "";
  if (!s.background) c.background.contrast = 0;
  else if (s.background_contrast > 0) c.background.contrast = s.background_contrast;
  if (!s.drift) {
    c.drift.clear();
    c.beam_lag_px = 0;
  }
  // BENCH_NO_JITTER=1 (diagnosis only): frames without per-line jitter and beam lag, the two
  // frame effects the bound and the oracles leave out.
  if (std::getenv("BENCH_NO_JITTER") != nullptr) {
    c.line_jitter_px = 0;
    c.beam_lag_px = 0;
  }
  auto& t = c.targets[0];  // the default needle tip
  dress_as(s.target, t);
  if (s.target_brightness > 0) t.brightness = s.target_brightness;
  t.x_px = s.start_x_px;
  t.y_px = s.start_y_px;
  t.phi_deg = s.start_phi_deg;
  auto& tr = t.trajectory;
  tr = config::TrajectoryConfig{};
  tr.margin_px = 110;
  if (s.motion == "static") {
    tr.kind = "static";
  } else if (s.motion == "smooth") {
    tr.kind = "sine";
    tr.amplitude_x_px = 60;
    tr.amplitude_y_px = 30;
    tr.amplitude_phi_deg = 20;
    tr.period_s = 4;
  } else if (s.motion == "fast") {
    tr.kind = "linear";  // ~4-5 px per 192² frame (≈10 ms), bouncing off the bounds
    tr.vx_px_s = 400;
    tr.vy_px_s = 250;
  } else if (s.motion == "spin") {
    tr.kind = "spin";  // ≈ 4.5° per 192² frame: faster than the paper could follow
    tr.omega_deg_s = 450;
  } else if (s.motion == "step") {
    tr.kind = "steps";
    tr.steps = 1;
    tr.period_s = s.step_period_s;
    tr.amplitude_x_px = s.step_x_px;
    tr.amplitude_y_px = s.step_y_px;
  } else if (s.motion == "jump") {
    tr.kind = "jumps";
    tr.period_s = 0.5;
    tr.amplitude_phi_deg = 90;
  }
  if (s.scale_to != 1.0 || s.scale_from != 1.0) {
    t.scale.from = s.scale_from;
    t.scale.to = s.scale_to;
    t.scale.ramp_s = s.run_s();
  }
  if (s.jaws && s.target == "gripper") {
    t.jaws.amplitude = s.jaws_amplitude_px;  // 0 → a → 0 → −a px: open and close
    t.jaws.period_s = s.jaws_period_s;
  }
  if (s.jaws_open_px != 0 && s.target == "gripper") t.jaws = config::TimeProfile::constant(s.jaws_open_px);
  if (s.charging_defocus) {
    c.charging_gain.from = 1.0;
    c.charging_gain.to = 0.65;
    c.charging_gain.ramp_s = s.run_s();
    c.charging_gain.amplitude = 0.1;
    c.charging_gain.period_s = 0.3;
    c.charging_offset.to = 0.08;
    c.charging_offset.ramp_s = s.run_s();
    c.defocus_px.to = 1.5;
    c.defocus_px.ramp_s = s.run_s();
    c.detector_tau_ns = 120;
  }
  if (s.detector_tau_ns > 0) c.detector_tau_ns = s.detector_tau_ns;
  c.targets[1].enabled = false;
  return c;
}

// One frame of a run as the benchmark needs it afterwards: when it was scanned and the truth.
struct FrameRecord {
  std::int64_t t_start_ns = 0;
  double t_mid_s = 0;  // mid-scan, seconds since the source started
  hal::TargetTruth truth;
  hal::TargetTruth second;  // the scene's second target (a twin: edit_run), when present
  // Target 0 when the beam passed its pose point (simulator scenes; the warped scene: mid-scan).
  // A full-field frame of a moving target shows it there, up to half the field's scan time away
  // from mid-scan.
  hal::TargetTruth as_scanned;
};

// A peer tracker's pose for one frame (run_peer).
struct PeerPose {
  bool valid = false;  // the peer reported a pose (ViSP: did not throw or diverge)
  double x_px = 0, y_px = 0, phi_deg = 0, scale = 1;
  double time_us = 0, cpu_us = 0;  // wall clock, thread CPU time
  hal::TargetTruth truth;
};

// A pose's angle error as the tracker declares its angle: modulo 360°/angle_order (a pattern
// that looks the same turned by that much, PoseEstimate::angle_order), in [0, 180/order]. The
// declaration is the tracker's, never the harness's.
inline double declared_angle_error_deg(const PoseEstimate& e, double truth_phi_deg) noexcept {
  return std::fabs(std::remainder(e.phi_deg - truth_phi_deg, 360.0 / std::max<int>(1, e.angle_order)));
}

// CPU time of the calling thread: what a computation costs, whatever else shares the cores.
inline std::int64_t thread_cpu_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct RunStats {
  int frames = 0, tracked = 0, lost = 0, searches = 0;
  double sum_px2 = 0, max_px = 0, sum_deg2 = 0, max_deg = 0;
  double sum_dx = 0, sum_dy = 0;  // signed, for the bias
  int err_n = 0;
  int recovery_max = 0;  // frames from a jump until TRACKING with error < 1 px again
  int false_tracking = 0;  // TRACKING poses more than 3 px off the truth (a false match)
  double false_max_px = 0;
  int jumps = 0;
  double acquire_ms = 0;
  std::vector<double> compute_us;
  std::vector<double> compute_cpu_us;  // the same on the thread's CPU clock (not inflated by other processes)
  double rms_px() const { return err_n ? std::sqrt(sum_px2 / err_n) : 0; }
  double rms_deg() const { return err_n ? std::sqrt(sum_deg2 / err_n) : 0; }
  double tracked_share() const { return frames ? static_cast<double>(tracked) / frames : 0; }
};

class SimHarness {
 public:
  SimHarness(const Scenario& s, const config::TrackerConfig& tc) : s_(s) {
    limits_.field_w = s.field_w;
    limits_.field_h = s.field_h;
    limits_.max_roi_w = std::max(256, tc.roi_size_px);
    limits_.max_roi_h = std::max(256, tc.roi_size_px);
    sim_cfg_ = make_sim_config(s);
    std::vector<PatternSet> sets(1);
    if (s.target == "warped") {
      // Simulator-free: the exact crop as pattern; frames from the warped image, 16-bit levels.
      warped_ = true;
      limits_.bits = 16;
      pattern_ = warped_scene().pattern(kWarpCx, kWarpCy, tc.pattern_size_px);
      const auto& t = sim_cfg_.targets[0];
      trajectory_ = hal::Trajectory(t.trajectory, {t.x_px, t.y_px, t.phi_deg}, s.field_w, s.field_h, s.seed * 1000003ull);
    } else {
      // The pattern: the target at rest and φ = 0, averaged like an operator would record it.
      config::SimConfig pat_cfg = sim_cfg_;
      pat_cfg.targets[0].x_px = s.field_w / 2.0;
      pat_cfg.targets[0].y_px = s.field_h / 2.0;
      pat_cfg.targets[0].scale = config::TimeProfile::constant(1.0);  // recorded at the pattern's own size
      if (s.pattern_lag_free) pat_cfg.detector_tau_ns = 0;
      if (s.jaws_open_px != 0) pat_cfg.targets[0].jaws = config::TimeProfile::constant(0.0);  // recorded closed
      pattern_ = hal::render_sim_pattern(pat_cfg, limits_, 0, tc.pattern_size_px, s.pattern_frames, pattern_dwell(), 777);
      sets[0].dwell_ns = s.pattern_lag_free || !s.pattern_dwell_told ? 0 : pattern_dwell();
      if (s.shape_mask)
        sets[0].mask = pipeline::to_pattern_image(
            hal::render_sim_pattern_mask(pat_cfg, limits_, 0, tc.pattern_size_px, s.shape_mask_rigid_only));
      if (s.edit_run) s.edit_run(sim_cfg_);
      sim_ = std::make_unique<hal::SimSource>(limits_, sim_cfg_);
    }
    sets[0].image = pipeline::to_pattern_image(pattern_);
    sets[0].nm_per_px = 40;
    if (!warped_) {
      config::SimConfig run_cfg = sim_cfg_;
      if (!s.target_in_field) {
        run_cfg.targets[0].x_px = -4.0 * s.field_w;  // far outside: not even its rim is scanned
        run_cfg.targets[0].trajectory = config::TrajectoryConfig{};
        sim_ = std::make_unique<hal::SimSource>(limits_, run_cfg);
      }
      if (s.vanish_after >= 0) {
        config::SimConfig gone = run_cfg;
        gone.targets[0].enabled = false;
        sim_gone_ = std::make_unique<hal::SimSource>(limits_, gone);
      }
    }
    // tracker.refine.black_level is the detector's: the simulator's output offset, none for the
    // warped crop (Poisson electrons scaled to the image's levels).
    config::TrackerConfig tcd = tc;
    tcd.refine.black_level = warped_ ? 0.0 : sim_cfg_.output_offset;
    if (!warped_ && s.tell_detector_tau && !(tcd.detector_tau_ns > 0))
      tcd.detector_tau_ns = s.told_detector_tau_ns > 0 ? s.told_detector_tau_ns : sim_cfg_.detector_tau_ns;
    tracker_ = Tracker::create(tcd, std::move(sets), limits_, status_);
    pixels_.assign(static_cast<std::size_t>(s.field_w) * s.field_h, 0);
    out_.resize(static_cast<std::size_t>(s.frames));
    truth_.resize(static_cast<std::size_t>(s.frames));
    records_.resize(static_cast<std::size_t>(s.frames));
    next_rois_.resize(static_cast<std::size_t>(s.frames));
  }
  std::uint32_t pattern_dwell() const { return s_.pattern_dwell_ns > 0 ? s_.pattern_dwell_ns : s_.dwell_ns; }
  // The ROI the tracker asked for after frame f (centred on its prediction for frame f + 1).
  const std::vector<pose::Roi>& next_rois() const { return next_rois_; }
  const hal::Image& pattern() const { return pattern_; }
  const hal::ScanLimits& limits() const { return limits_; }
  const config::SimConfig& sim_config() const { return sim_cfg_; }
  const std::vector<FrameRecord>& records() const { return records_; }

  // Renders roi as scanned from t (virtual clock) with noise stream seq; truth: target 0 at mid-scan.
  void render(const hal::Roi& roi, std::int64_t t, std::uint64_t seq, hal::Pixel* out, hal::TargetTruth* truth,
              double* t_mid_s = nullptr, hal::TargetTruth* as_scanned = nullptr) {
    const double mid = static_cast<double>(t - hal::SimSource::kVirtualEpochNs) * 1e-9 +
                       0.5 * static_cast<double>(limits_.scan_time_ns(roi.w, roi.h, s_.dwell_ns)) * 1e-9;
    if (t_mid_s) *t_mid_s = mid;
    if (!warped_) {
      // Faults: the target gone from frame vanish_after on; blank or saturated frames.
      hal::SimSource& src = (sim_gone_ && static_cast<long long>(seq) >= s_.vanish_after) ? *sim_gone_ : *sim_;
      src.render(roi, s_.dwell_ns, t, seq, out, truth);
      if (as_scanned) *as_scanned = src.truth_as_scanned(0, roi, s_.dwell_ns, t);
      if (s_.frames_kind != Scenario::Frames::kScene) {
        const hal::Pixel v = s_.frames_kind == Scenario::Frames::kBlank ? 0 : 255;
        std::fill(out, out + static_cast<std::ptrdiff_t>(roi.w) * roi.h, v);
      }
      if (s_.frame_fault) s_.frame_fault(seq, roi, out, static_cast<hal::Pixel>((1u << limits_.bits) - 1));
      return;
    }
    // Test helper: WarpScene::render allocates its output (warp_out_ keeps its capacity).
    // Scanned row by row as the simulator's scenes are: each row shows the target where it is
    // when that row is scanned (a moving target shows sheared and stretched).
    const double row_s = static_cast<double>(limits_.scan_time_ns(roi.w, roi.h, s_.dwell_ns)) * 1e-9 / roi.h;
    const double start_s = static_cast<double>(t - hal::SimSource::kVirtualEpochNs) * 1e-9;
    const auto pose_at = [&](double at_s) {
      hal::Pose2 q = trajectory_.at(at_s);
      if (static_cast<long long>(seq) == s_.kick_frame) {
        q.x_px += s_.kick_x_px;
        q.y_px += s_.kick_y_px;
        q.phi_deg += s_.kick_phi_deg;
      }
      return q;
    };
    const auto row_time = [&](double row) { return start_s + (std::clamp(row - roi.y, 0.0, roi.h - 1.0) + 0.5) * row_s; };
    warped_scene().render_rows(kWarpCx, kWarpCy, [&](int py) { return pose_at(row_time(py)); }, s_.field_w, s_.field_h,
                               warp_out_, s_.noise ? s_.dose_e : 0.0, s_.seed * 7919 + seq, roi);
    std::copy(warp_out_.begin(), warp_out_.end(), out);
    if (s_.detector_tau_ns > 0) low_pass_lines(roi, out);
    const hal::Pose2 p = pose_at(mid);
    for (int i = 0; i < hal::kMaxTargets; ++i) truth[i] = hal::TargetTruth{};
    truth[0] = {p.x_px, p.y_px, p.phi_deg, true};
    if (as_scanned) {
      // When the beam passed the pose point: its row's time, found by iterating row -> time -> row.
      hal::Pose2 q = p;
      for (int k = 0; k < 3; ++k) q = pose_at(row_time(std::round(q.y_px)));
      *as_scanned = {q.x_px, q.y_px, q.phi_deg, true};
    }
  }

  // Another tracker on the same sequence: frame f is scanned from the same virtual time as
  // the tracker's frame f, over the ROI the peer asks for, with its own noise. Peer:
  //   hal::Roi roi(int fw, int fh);  PeerPose track(const hal::Roi&, const hal::Pixel*, int bits);
  //   void start(x, y, phi_deg, scale) — called with the first frame's truth before its track().
  // The peer's first ROI comes from its own start pose (set it near the first truth).
  template <class Peer>
  std::vector<PeerPose> run_peer(Peer& peer) {
    std::vector<PeerPose> out(static_cast<std::size_t>(s_.frames));
    std::vector<hal::Pixel> px;
    for (int f = 0; f < s_.frames; ++f) {
      const hal::Roi roi = peer.roi(s_.field_w, s_.field_h);
      px.resize(static_cast<std::size_t>(roi.w) * roi.h);
      hal::TargetTruth truth[hal::kMaxTargets];
      render(roi, records_[static_cast<std::size_t>(f)].t_start_ns, (1ull << 40) + static_cast<std::uint64_t>(f), px.data(),
             truth);
      if (f == 0) peer.start(truth[0].x_px, truth[0].y_px, truth[0].phi_deg, truth[0].scale);  // started at the truth
      PeerPose& p = out[static_cast<std::size_t>(f)];
      p = peer.track(roi, px.data(), limits_.bits);
      p.truth = truth[0];
    }
    return out;
  }
  const rt::Status& status() const { return status_; }
  Tracker* tracker() { return tracker_.get(); }

  // The detector's line low-pass on a rendered ROI, as the simulator's detect_line applies it:
  // y_i = y_(i−1) + a·(x_i − y_(i−1)), a = 1 − exp(−dwell/τ), settled on each line's first pixel.
  void low_pass_lines(const hal::Roi& roi, hal::Pixel* px) const noexcept {
    const double a = 1.0 - std::exp(-static_cast<double>(s_.dwell_ns) / s_.detector_tau_ns);
    for (int y = 0; y < roi.h; ++y) {
      hal::Pixel* row = px + static_cast<std::ptrdiff_t>(y) * roi.w;
      double v = row[0];
      for (int x = 0; x < roi.w; ++x) {
        v += a * (row[x] - v);
        row[x] = static_cast<hal::Pixel>(std::lround(v));
      }
    }
  }

  // The loop: only RT calls on the tracker (allocation tests arm the counter around it).
  void run() noexcept {
    std::int64_t t = hal::SimSource::kVirtualEpochNs;
    for (int f = 0; f < s_.frames; ++f) {
      hal::FrameMeta meta;
      meta.seq = static_cast<std::uint64_t>(f);
      meta.roi = tracker_->next_roi();
      meta.field_w = s_.field_w;
      meta.field_h = s_.field_h;
      meta.dwell_ns = s_.dwell_ns;
      meta.t_scan_start_ns = t;
      meta.bits = limits_.bits;
      FrameRecord& rec = records_[static_cast<std::size_t>(f)];
      rec.t_start_ns = t;
      render(meta.roi, t, meta.seq, pixels_.data(), meta.truth, &rec.t_mid_s, &rec.as_scanned);
      rec.truth = meta.truth[0];
      rec.second = meta.truth[1];
      // The scan ends when its last row is scanned (as a scan source stamps it); the tracker's
      // compute (modelled) comes after it, before the next scan.
      meta.t_scan_end_ns = t + limits_.scan_time_ns(meta.roi.w, meta.roi.h, s_.dwell_ns);
      t = meta.t_scan_end_ns + 500'000;
      const std::int64_t t0 = rt::now_ns(), c0 = thread_cpu_ns();
      {
        // Heap calls made inside the tracker (the simulator's own are not its business).
        rt::alloc::ScopedArm arm;
        const std::uint64_t before = rt::alloc::this_thread_allocations();
        out_[static_cast<std::size_t>(f)] = tracker_->update(pipeline::to_pose_frame(meta, pixels_.data()));
        next_rois_[static_cast<std::size_t>(f)] = tracker_->next_roi();
        tracker_allocations_ += rt::alloc::this_thread_allocations() - before;
      }
      compute_ns_[static_cast<std::size_t>(f) % compute_ns_.size()] = rt::now_ns() - t0;
      compute_cpu_ns_[static_cast<std::size_t>(f) % compute_ns_.size()] = thread_cpu_ns() - c0;
      if (f < static_cast<int>(compute_ns_.size())) n_compute_ = f + 1;
      truth_[static_cast<std::size_t>(f)] = meta.truth[0];
      // Learned appearance: the non-RT rebuild, synchronously between frames (the product
      // runs the same call on a worker thread); outside the armed scope and the timing.
      tracker_->maintain_appearance();
    }
  }

  RunStats stats() const {
    RunStats r;
    r.frames = s_.frames;
    bool acquired = false;
    int since_jump = -1;
    for (int f = 0; f < s_.frames; ++f) {
      const PoseEstimate& e = out_[static_cast<std::size_t>(f)];
      const hal::TargetTruth& tr = truth_[static_cast<std::size_t>(f)];
      if (f > 0 && s_.motion == "jump") {
        const hal::TargetTruth& prev = truth_[static_cast<std::size_t>(f - 1)];
        if (std::hypot(tr.x_px - prev.x_px, tr.y_px - prev.y_px) > 20) {
          since_jump = 0;
          ++r.jumps;
        }
      }
      if (e.searched) ++r.searches;
      const double dx = e.x_px - tr.x_px, dy = e.y_px - tr.y_px;
      double dphi = std::fmod(e.phi_deg - tr.phi_deg + 540.0, 360.0) - 180.0;
      const double dpos = std::hypot(dx, dy);
      if (e.state == TrackState::kTracking) {
        ++r.tracked;
        if (dpos > 3.0) {
          ++r.false_tracking;
          r.false_max_px = std::max(r.false_max_px, dpos);
        }
        if (!acquired) acquired = true;
        if (e.reason_bits == 0 && since_jump != 0) {  // the jump frame itself saw the old place
          ++r.err_n;
          r.sum_px2 += dpos * dpos;
          r.sum_deg2 += dphi * dphi;
          r.sum_dx += dx;
          r.sum_dy += dy;
          r.max_px = std::max(r.max_px, dpos);
          r.max_deg = std::max(r.max_deg, std::fabs(dphi));
        }
      } else {
        ++r.lost;
      }
      if (since_jump >= 0) {
        if (e.state == TrackState::kTracking && dpos < 1.0 && since_jump > 0) {
          r.recovery_max = std::max(r.recovery_max, since_jump);
          since_jump = -1;
        } else {
          ++since_jump;
        }
      }
    }
    for (int i = 0; i < n_compute_; ++i) r.compute_us.push_back(compute_ns_[static_cast<std::size_t>(i)] * 1e-3);
    for (int i = 0; i < n_compute_; ++i) r.compute_cpu_us.push_back(compute_cpu_ns_[static_cast<std::size_t>(i)] * 1e-3);
    return r;
  }
  const std::vector<PoseEstimate>& poses() const { return out_; }
  std::uint64_t tracker_allocations() const { return tracker_allocations_; }
  const std::vector<hal::TargetTruth>& truth() const { return truth_; }

 private:
  Scenario s_;
  hal::ScanLimits limits_;
  config::SimConfig sim_cfg_;
  std::unique_ptr<hal::SimSource> sim_;
  bool warped_ = false;
  hal::Trajectory trajectory_;
  std::vector<hal::Pixel> warp_out_;
  hal::Image pattern_;
  std::vector<FrameRecord> records_;
  std::vector<pose::Roi> next_rois_;
  std::unique_ptr<hal::SimSource> sim_gone_;  // the same scene without the target (vanish_after)
  std::unique_ptr<Tracker> tracker_;
  rt::Status status_;
  std::vector<hal::Pixel> pixels_;
  std::vector<PoseEstimate> out_;
  std::vector<hal::TargetTruth> truth_;
  std::array<std::int64_t, 4096> compute_ns_{};
  std::array<std::int64_t, 4096> compute_cpu_ns_{};
  int n_compute_ = 0;
  std::uint64_t tracker_allocations_ = 0;
};

}  // namespace sempose::pose::testing
