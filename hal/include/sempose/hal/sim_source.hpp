// The simulated SEM as a ScanSource (README: The simulated SEM). start() renders the whole ROI at once,
// line by line at each line's own time (targets move during the scan, like a real beam
// scan), into the slot; poll() only compares the clock with the scan end.
//   real clock:    poll() is kBusy until CLOCK_MONOTONIC >= start + scan time.
//   virtual clock: start() begins at the virtual now; poll() returns kDone and moves the
//                  virtual now to the scan end; advance_virtual_ns() adds modelled compute.
// Virtual time starts at 1 s (0 means "not reached" in FrameMeta); trajectories and drift use
// t = now − (creation time) in seconds. Frames are reproducible from (seed, seq) in virtual time.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "sempose/config/sim_config.hpp"
#include "sempose/hal/image.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/hal/scan_timer.hpp"
#include "sempose/hal/sim_rng.hpp"
#include "sempose/hal/sim_scene.hpp"
#include "sempose/hal/trajectory.hpp"

namespace sempose::hal {

class SimSource final : public TimedScanSource {
 public:
  static constexpr std::int64_t kVirtualEpochNs = ScanTimer::kVirtualEpochNs;

  // Setup: builds the scene; throws std::runtime_error with a message on a bad config.
  SimSource(const ScanLimits& limits, const config::SimConfig& cfg);

  const ScanLimits& limits() const noexcept override { return limits_; }
  StartResult start(const ScanRequest& req, FrameSlot& slot) noexcept override;

  // Renders roi as scanned from t_start_ns (the source's clock) into out (roi.w·roi.h
  // pixels) and fills truth[0..target count) with the poses at mid-scan. RT-safe.
  void render(const Roi& roi, std::uint32_t dwell_ns, std::int64_t t_start_ns, std::uint64_t seq, Pixel* out,
              TargetTruth* truth) noexcept;
  // Target t's truth as a scan of roi from t_start_ns shows it: its pose (drift included) at the
  // moment the beam passed its pose point, found by iterating point -> pixel time -> point. For a
  // ROI centred on the target that is mid-scan (render()'s truth); a 640x480 field takes ~78 ms
  // at 250 ns, and a target moving 100 px/s is ~4 px from its mid-scan pose when the beam meets it
  // near the field's top or bottom. `sempose sim` writes this truth for its full-field frames.
  TargetTruth truth_as_scanned(std::size_t t, const Roi& roi, std::uint32_t dwell_ns, std::int64_t t_start_ns) noexcept;
  std::uint8_t target_count() const noexcept { return static_cast<std::uint8_t>(scene_.targets().size()); }
  const SimScene& scene() const noexcept { return scene_; }

  // Target t's pose and shape at t_s seconds after the source started (trajectory, scale,
  // jaws; drift not included). Tests and benchmarks use it with SimScene::render_mean.
  SimTargetPose target_pose(std::size_t t, double t_s) noexcept;
  // Seconds since the source started, for a time on its clock.
  double seconds(std::int64_t t_ns) const noexcept { return static_cast<double>(t_ns - epoch_ns_) * 1e-9; }

 private:
  void drift_at(double t_s, double& dx, double& dy) const noexcept;
  // Target t's truth at time t_s as it appears (drift included, jitter not); present when
  // enabled and inside the field.
  TargetTruth truth_at(std::size_t t, double t_s) noexcept;
  // One line's scene brightness -> detector -> output counts: charging gain/offset, Poisson
  // electrons × Gamma gain + read noise (or the mean), the bandwidth low-pass, quantisation.
  void detect_line(const float* b, int n, double gain, double offset, std::uint32_t dwell_ns, Pixel* dst) noexcept;
  void line_poses(double t_line, float qy, std::array<LinePose, kMaxTargets>& pose) noexcept;

  ScanLimits limits_;
  SimScene scene_;
  std::int64_t epoch_ns_;
  std::array<Trajectory, kMaxTargets> trajectories_{};
  std::array<float, 64> lag_px_{};  // beam position lag for the first pixels of a line
  std::vector<float> line_;         // one line's scene brightness (field width)
  // Defocus (only when configured): the ROI plus a 3σ margin rendered first, then blurred.
  std::vector<float> defocus_buf_, defocus_tmp_;
  int defocus_margin_max_ = 0;
  SimRng rng_{0, 0};
  SimRng jitter_rng_{0, 0};  // line jitter when defocus renders all lines before the noise
  std::uint64_t seq_ = 0;
};

// The pattern an operator would record (the paper averaged 10 frames): target target_index at
// φ = 0, centred in a size_px x size_px crop over its background, the mean of average_frames
// noisy scans at dwell_ns; drift and motion off. The scene is cfg's (cfg.seed makes the
// procedural background and textures); `seed` only selects the noise of the averaged scans.
// Setup-time; throws on a bad index/size.
Image render_sim_pattern(const config::SimConfig& cfg, const ScanLimits& limits, int target_index, int size_px,
                         int average_frames, std::uint32_t dwell_ns, std::uint64_t seed);

// The same crop's shape mask: 255 where the target covers the pixel (its alpha >= 0.5), 0 on
// the background — what an operator draws around a recorded pattern. rigid_only: only the
// parts rigid with the pose point (a gripper's body), without the pixels its moving jaws can
// reach at any opening of their profile. Setup-time; throws.
Image render_sim_pattern_mask(const config::SimConfig& cfg, const ScanLimits& limits, int target_index, int size_px,
                              bool rigid_only = false);

}  // namespace sempose::hal
