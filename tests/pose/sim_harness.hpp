// Closed-loop tracking on the simulated SEM for tests and benchmarks: the tracker asks for a
// ROI, the simulator renders it at the virtual time of its scan, the tracker updates, the
// pose is compared with the simulator's truth (mid-scan pose). Setup allocates; run() only
// calls the RT methods.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
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
  bool shape_mask = false;  // give the tracker the target's shape mask with its pattern (opt-in, see README)
};

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
  if (!s.drift) {
    c.drift.clear();
    c.beam_lag_px = 0;
  }
  auto& t = c.targets[0];  // the default needle tip
  if (s.target == "lamella_post") {
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
  } else if (s.target == "lamella") {
    t.texture = config::TextureConfig{};
    t.texture.source = "lamella";
    t.width_px = 100;
    t.height_px = 64;
  } else {
    t.texture.path = std::string(SEMPOSE_TEST_DATA) + "/sem/needle_contact_eb.pgm";
  }
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
  } else if (s.motion == "jump") {
    tr.kind = "jumps";
    tr.period_s = 0.5;
    tr.amplitude_phi_deg = 90;
  }
  c.targets[1].enabled = false;
  return c;
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
    // The pattern: the target at rest and φ = 0, averaged like an operator would record it.
    config::SimConfig pat_cfg = sim_cfg_;
    pat_cfg.targets[0].x_px = s.field_w / 2.0;
    pat_cfg.targets[0].y_px = s.field_h / 2.0;
    std::vector<PatternSet> sets(1);
    sets[0].image = pipeline::to_pattern_image(hal::render_sim_pattern(pat_cfg, limits_, 0, tc.pattern_size_px, 10, s.dwell_ns, 777));
    if (s.shape_mask)
      sets[0].mask = pipeline::to_pattern_image(hal::render_sim_pattern_mask(pat_cfg, limits_, 0, tc.pattern_size_px));
    sets[0].nm_per_px = 40;
    sim_ = std::make_unique<hal::SimSource>(limits_, sim_cfg_);
    tracker_ = Tracker::create(tc, std::move(sets), limits_, status_);
    pixels_.assign(static_cast<std::size_t>(s.field_w) * s.field_h, 0);
    out_.resize(static_cast<std::size_t>(s.frames));
    truth_.resize(static_cast<std::size_t>(s.frames));
  }
  const rt::Status& status() const { return status_; }
  Tracker* tracker() { return tracker_.get(); }

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
      sim_->render(meta.roi, s_.dwell_ns, t, meta.seq, pixels_.data(), meta.truth);
      t += limits_.scan_time_ns(meta.roi.w, meta.roi.h, s_.dwell_ns) + 500'000;  // + modelled compute
      meta.t_scan_end_ns = t;
      const std::int64_t t0 = rt::now_ns();
      {
        // Heap calls made inside the tracker (the simulator's own are not its business).
        rt::alloc::ScopedArm arm;
        const std::uint64_t before = rt::alloc::this_thread_allocations();
        out_[static_cast<std::size_t>(f)] = tracker_->update(pipeline::to_pose_frame(meta, pixels_.data()));
        const pose::Roi next = tracker_->next_roi();
        (void)next;
        tracker_allocations_ += rt::alloc::this_thread_allocations() - before;
      }
      compute_ns_[static_cast<std::size_t>(f) % compute_ns_.size()] = rt::now_ns() - t0;
      if (f < static_cast<int>(compute_ns_.size())) n_compute_ = f + 1;
      truth_[static_cast<std::size_t>(f)] = meta.truth[0];
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
  std::unique_ptr<Tracker> tracker_;
  rt::Status status_;
  std::vector<hal::Pixel> pixels_;
  std::vector<PoseEstimate> out_;
  std::vector<hal::TargetTruth> truth_;
  std::array<std::int64_t, 4096> compute_ns_{};
  int n_compute_ = 0;
  std::uint64_t tracker_allocations_ = 0;
};

}  // namespace sempose::pose::testing
