#include "sempose/hal/sim_source.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "sempose/hal/scan_request_check.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::hal {

namespace {
constexpr double kTwoPi = 6.283185307179586;
constexpr double kDegToRad = kTwoPi / 360.0;
}  // namespace

SimSource::SimSource(const ScanLimits& limits, const config::SimConfig& cfg)
    : TimedScanSource(cfg.clock == "virtual"),
      limits_(limits),
      scene_(cfg, limits),
      epoch_ns_(timer_.is_virtual() ? kVirtualEpochNs : rt::now_ns()) {
  if (limits.bits != 8 && limits.bits != 16) throw std::runtime_error("scan.bits must be 8 or 16");
  for (std::size_t i = 0; i < cfg.targets.size(); ++i) {
    const auto& t = cfg.targets[i];
    trajectories_[i] = Trajectory(t.trajectory, {t.x_px, t.y_px, t.phi_deg}, limits.field_w, limits.field_h,
                                  cfg.seed * 1000003ull + i);
  }
  for (std::size_t i = 0; i < lag_px_.size(); ++i) {
    lag_px_[i] = static_cast<float>(cfg.beam_lag_px * std::exp(-static_cast<double>(i) / cfg.beam_lag_len_px));
  }
  line_.assign(static_cast<std::size_t>(limits.field_w), 0.0f);
  if (!cfg.defocus_px.is_constant() || cfg.defocus_px.from > 0) {
    const double worst = std::min(cfg.defocus_px.max_abs(), kMaxBlurSigma);
    defocus_margin_max_ = static_cast<int>(std::ceil(3.0 * worst));
    const std::size_t n = static_cast<std::size_t>(limits.field_w + 2 * defocus_margin_max_) *
                          static_cast<std::size_t>(limits.field_h + 2 * defocus_margin_max_);
    defocus_buf_.assign(n, 0.0f);
    defocus_tmp_.assign(n, 0.0f);
  }
}

SimTargetPose SimSource::target_pose(std::size_t t, double t_s) noexcept {
  SimTargetPose p;
  if (t >= scene_.targets().size()) return {false};
  const config::SimTargetConfig& tc = scene_.config().targets[t];
  const Pose2 q = trajectories_[t].at(t_s);
  p.active = scene_.targets()[t].enabled;
  p.x_px = q.x_px, p.y_px = q.y_px, p.phi_deg = q.phi_deg;
  p.scale = tc.scale.is_constant() ? tc.scale.from : tc.scale.at(t_s);
  p.jaw_open_px = tc.jaws.is_constant() ? tc.jaws.from : tc.jaws.at(t_s);
  return p;
}

void SimSource::line_poses(double t_line, float qy, std::array<LinePose, kMaxTargets>& pose) noexcept {
  const std::size_t n_targets = scene_.targets().size();
  for (std::size_t t = 0; t < n_targets; ++t) {
    pose[t] = LinePose{};
    if (!scene_.targets()[t].enabled) continue;
    pose[t] = scene_.line_pose(t, target_pose(t, t_line), qy);
  }
}

void SimSource::detect_line(const float* b, int n, double gain, double offset, std::uint32_t dwell_ns,
                            Pixel* dst) noexcept {
  const config::SimConfig& cfg = scene_.config();
  // Expected electrons for brightness 1; output counts per electron so that brightness 1
  // at the mean gain lands on output_white of full scale, whatever the dwell (the operator's
  // contrast setting): a shorter dwell gives the same mean and more noise.
  const double n_white = std::max(1e-9, cfg.electrons_per_pixel(dwell_ns));
  const double maxv = limits_.max_value();
  const double counts_per_e = cfg.output_white * maxv / n_white;
  const double offset_counts = cfg.output_offset * maxv + 0.5;  // + 0.5: round to nearest
  const double k = cfg.detector_gain_shape, inv_k = 1.0 / k;
  const bool noise = cfg.noise;
  const double read_noise = cfg.read_noise_e;
  // Detector bandwidth: a first-order low-pass sampled at the end of each dwell, exact for a
  // signal constant over the dwell: y_i = y_(i−1) + a·(x_i − y_(i−1)), a = 1 − exp(−dwell/τ).
  // The filter starts settled on the line's first pixel (the flyback's blanking is not modelled).
  const bool low_pass = cfg.detector_tau_ns > 0;
  const double a_lp = low_pass ? 1.0 - std::exp(-static_cast<double>(dwell_ns) / cfg.detector_tau_ns) : 1.0;
  double y_lp = 0;
  for (int i = 0; i < n; ++i) {
    const double mean_e = std::max(0.0, b[i] * gain + offset) * n_white;
    double e;
    if (noise) {
      // Detector cascade: Poisson electrons, each with a Gamma(k, 1/k) gain (mean 1):
      // their sum is Gamma(n·k)/k. Then Gaussian read noise.
      const double ne = rng_.poisson(mean_e);
      e = ne > 0 ? rng_.fast_gamma(ne * k) * inv_k : 0.0;
      if (read_noise > 0) e += read_noise * rng_.fast_normal();
    } else {
      e = mean_e;
    }
    if (low_pass) {
      y_lp = i == 0 ? e : y_lp + a_lp * (e - y_lp);
      e = y_lp;
    }
    const double counts = offset_counts + e * counts_per_e;
    dst[i] = static_cast<Pixel>(counts <= 0.0 ? 0.0 : counts >= maxv ? maxv : counts);
  }
}

void SimSource::drift_at(double t_s, double& dx, double& dy) const noexcept {
  dx = dy = 0;
  for (const auto& d : scene_.config().drift) {
    const double a = d.amplitude_px * std::sin(kTwoPi * t_s / d.period_s + d.phase_deg * kDegToRad);
    dx += a * std::cos(d.direction_deg * kDegToRad);
    dy += a * std::sin(d.direction_deg * kDegToRad);
  }
}

StartResult SimSource::start(const ScanRequest& req, FrameSlot& slot) noexcept {
  if (timer_.busy()) return StartResult::kBusy;
  std::uint32_t dwell = 0;
  const StartResult check = check_scan_request(limits_, req, slot.capacity_pixels, dwell);
  if (check != StartResult::kStarted) return check;
  const std::int64_t t0 = now_ns();
  timer_.begin(slot, req, limits_, dwell, seq_, t0);
  slot.meta.truth_count = target_count();
  render(req.roi, dwell, t0, seq_, slot.pixels, slot.meta.truth);
  ++seq_;
  return StartResult::kStarted;
}

void SimSource::render(const Roi& roi, std::uint32_t dwell_ns, std::int64_t t_start_ns, std::uint64_t seq,
                       Pixel* out, TargetTruth* truth) noexcept {
  const config::SimConfig& cfg = scene_.config();
  const std::size_t n_targets = scene_.targets().size();
  rng_.reseed(cfg.seed, seq);
  const double line_ns = static_cast<double>(roi.w) * dwell_ns + limits_.line_flyback_ns;
  const double t_mid = seconds(t_start_ns) + 0.5 * static_cast<double>(limits_.scan_time_ns(roi.w, roi.h, dwell_ns)) * 1e-9;
  const int lag_n = static_cast<int>(lag_px_.size());
  const bool charging = !cfg.charging_gain.is_constant() || cfg.charging_gain.from != 1.0 ||
                        !cfg.charging_offset.is_constant() || cfg.charging_offset.from != 0.0;
  // Per line: the time the beam scans it, and the brightness gain/offset at that time.
  auto line_time = [&](int row) { return seconds(t_start_ns) + (row * line_ns + 0.5 * roi.w * dwell_ns) * 1e-9; };
  auto photometry = [&](double t_line, double& gain, double& offset) {
    gain = 1.0 + cfg.brightness_drift * std::sin(kTwoPi * t_line / cfg.brightness_drift_period_s);
    offset = 0.0;
    if (charging) {
      gain *= cfg.charging_gain.at(t_line);
      offset = cfg.charging_offset.at(t_line);
    }
  };
  std::array<LinePose, kMaxTargets> pose{};
  const double defocus = defocus_buf_.empty() ? 0.0 : std::min(std::max(0.0, cfg.defocus_px.at(t_mid)), kMaxBlurSigma);
  if (defocus <= 0.05) {
    // Line by line: the beam scans each line at its own time (targets and drift per line).
    for (int row = 0; row < roi.h; ++row) {
      const double t_line = line_time(row);
      double dx = 0, dy = 0, gain = 1, offset = 0;
      drift_at(t_line, dx, dy);
      photometry(t_line, gain, offset);
      const double jitter = cfg.noise ? cfg.line_jitter_px * rng_.normal() : 0.0;
      const float qy = static_cast<float>(roi.y + row - dy);
      line_poses(t_line, qy, pose);
      scene_.compose_line(pose.data(), static_cast<float>(roi.x + jitter - dx), qy, lag_px_.data(), lag_n, 0, roi.w,
                          line_.data(), nullptr);
      detect_line(line_.data(), roi.w, gain, offset, dwell_ns, out + static_cast<std::size_t>(row) * roi.w);
    }
  } else {
    // Defocus: the beam spot is wider, so a pixel sees its neighbours on other lines too. The
    // ROI and a 3σ margin are composed first (jitter from its own stream), blurred, then detected.
    const int m = std::min(defocus_margin_max_, static_cast<int>(std::ceil(3.0 * defocus)));
    const int W = roi.w + 2 * m, H = roi.h + 2 * m;
    jitter_rng_.reseed(cfg.seed ^ 0x6A69747465720000ull, seq);
    for (int r = 0; r < H; ++r) {
      const double t_line = line_time(r - m);
      double dx = 0, dy = 0;
      drift_at(t_line, dx, dy);
      const double jitter = cfg.noise ? cfg.line_jitter_px * jitter_rng_.normal() : 0.0;
      const float qy = static_cast<float>(roi.y + r - m - dy);
      line_poses(t_line, qy, pose);
      scene_.compose_line(pose.data(), static_cast<float>(roi.x - m + jitter - dx), qy, lag_px_.data(), lag_n, -m, W,
                          &defocus_buf_[static_cast<std::size_t>(r) * W], nullptr);
    }
    gaussian_blur_in_place(defocus_buf_.data(), W, H, defocus, defocus_tmp_.data());
    for (int row = 0; row < roi.h; ++row) {
      double gain = 1, offset = 0;
      photometry(line_time(row), gain, offset);
      detect_line(&defocus_buf_[static_cast<std::size_t>(row + m) * W + m], roi.w, gain, offset, dwell_ns,
                  out + static_cast<std::size_t>(row) * roi.w);
    }
  }
  // Truth: each target's pose at mid-scan.
  for (std::size_t t = 0; t < n_targets && t < static_cast<std::size_t>(kMaxTargets); ++t) truth[t] = truth_at(t, t_mid);
  for (std::size_t t = n_targets; t < static_cast<std::size_t>(kMaxTargets); ++t) truth[t] = TargetTruth{};
}

TargetTruth SimSource::truth_as_scanned(std::size_t t, const Roi& roi, std::uint32_t dwell_ns,
                                        std::int64_t t_start_ns) noexcept {
  TargetTruth tr;
  if (t >= scene_.targets().size() || roi.w <= 0 || roi.h <= 0) return tr;
  const double line_ns = static_cast<double>(roi.w) * dwell_ns + limits_.line_flyback_ns;
  const double t0 = seconds(t_start_ns);
  // Start at mid-scan; the pixel time of the point moves by (speed x line time) per step, far
  // below 1 px, so three steps converge (a jump during the scan settles on either side of it).
  double ts = t0 + 0.5 * static_cast<double>(limits_.scan_time_ns(roi.w, roi.h, dwell_ns)) * 1e-9;
  for (int k = 0; k < 4; ++k) {
    tr = truth_at(t, ts);
    const double row = std::clamp(tr.y_px - roi.y, 0.0, roi.h - 1.0);
    const double col = std::clamp(tr.x_px - roi.x, 0.0, roi.w - 1.0);
    const double next = t0 + (std::round(row) * line_ns + col * dwell_ns) * 1e-9;
    if (k > 0 && std::fabs(next - ts) < 1e-7) break;
    ts = next;
  }
  return tr;
}

TargetTruth SimSource::truth_at(std::size_t t, double t_s) noexcept {
  const SimTargetPose p = target_pose(t, t_s);
  double dx = 0, dy = 0;
  drift_at(t_s, dx, dy);
  TargetTruth tr;
  tr.x_px = p.x_px + dx;
  tr.y_px = p.y_px + dy;
  tr.phi_deg = p.phi_deg;
  tr.scale = p.scale;
  tr.present = scene_.targets()[t].enabled && tr.x_px >= 0 && tr.y_px >= 0 && tr.x_px <= limits_.field_w - 1 &&
               tr.y_px <= limits_.field_h - 1;
  return tr;
}

namespace {
// Where the pattern crop of a target lies: centred on the target, clamped to the field.
void pattern_origin(const config::SimTargetConfig& t, const ScanLimits& limits, int size_px, std::int32_t& ox,
                    std::int32_t& oy) {
  const double half = (size_px - 1) / 2.0;
  ox = static_cast<std::int32_t>(std::clamp(std::lround(t.x_px - half), 0L, static_cast<long>(limits.field_w - size_px)));
  oy = static_cast<std::int32_t>(std::clamp(std::lround(t.y_px - half), 0L, static_cast<long>(limits.field_h - size_px)));
}
}  // namespace

Image render_sim_pattern(const config::SimConfig& cfg_in, const ScanLimits& limits, int target_index, int size_px,
                         int average_frames, std::uint32_t dwell_ns, std::uint64_t seed) {
  if (target_index < 0 || target_index >= static_cast<int>(cfg_in.targets.size())) {
    throw std::runtime_error("render_sim_pattern: target " + std::to_string(target_index) + " is not configured (" +
                             std::to_string(cfg_in.targets.size()) + " targets)");
  }
  if (size_px < 8 || size_px > limits.field_w || size_px > limits.field_h) {
    throw std::runtime_error("render_sim_pattern: size " + std::to_string(size_px) + " does not fit the field");
  }
  if (average_frames < 1) throw std::runtime_error("render_sim_pattern: average_frames must be >= 1");
  // Only this target, at rest, no drift: the operator records it with the stage still.
  // cfg.seed stays: it also generates the scene (procedural background and textures), and the
  // pattern must show the same scene the tracker will see. `seed` only selects the noise.
  config::SimConfig cfg = cfg_in;
  cfg.clock = "virtual";
  cfg.drift.clear();
  cfg.brightness_drift = 0;
  for (std::size_t i = 0; i < cfg.targets.size(); ++i) cfg.targets[i].enabled = static_cast<int>(i) == target_index;
  config::SimTargetConfig& t = cfg.targets[static_cast<std::size_t>(target_index)];
  const double half = (size_px - 1) / 2.0;
  std::int32_t ox = 0, oy = 0;
  pattern_origin(t, limits, size_px, ox, oy);
  t.x_px = ox + half;
  t.y_px = oy + half;
  t.phi_deg = 0;
  t.trajectory = config::TrajectoryConfig{};
  ScanLimits lim = limits;
  dwell_ns = static_cast<std::uint32_t>(std::clamp<std::uint64_t>(lim.round_dwell_ns(dwell_ns), lim.min_dwell_ns, lim.max_dwell_ns));
  SimSource src(lim, cfg);
  const std::size_t n = static_cast<std::size_t>(size_px) * size_px;
  std::vector<Pixel> frame(n);
  std::vector<double> sum(n, 0.0);
  TargetTruth truth[kMaxTargets];
  for (int f = 0; f < average_frames; ++f) {
    // Every frame at t = 0: no motion, only fresh noise and jitter.
    // Noise streams (seq) far from the ones of a run's frames (seq 0, 1, 2, ...).
    const std::uint64_t seq = ((seed + 1) << 32) + static_cast<std::uint64_t>(f);
    src.render({ox, oy, size_px, size_px}, dwell_ns, SimSource::kVirtualEpochNs, seq, frame.data(), truth);
    for (std::size_t i = 0; i < n; ++i) sum[i] += frame[i];
  }
  Image img;
  img.width = img.height = size_px;
  img.bits = lim.bits;
  img.pixels.resize(n);
  for (std::size_t i = 0; i < n; ++i) img.pixels[i] = static_cast<std::uint16_t>(std::lround(sum[i] / average_frames));
  return img;
}

Image render_sim_pattern_mask(const config::SimConfig& cfg, const ScanLimits& limits, int target_index, int size_px,
                              bool rigid_only) {
  if (target_index < 0 || target_index >= static_cast<int>(cfg.targets.size())) {
    throw std::runtime_error("render_sim_pattern_mask: target " + std::to_string(target_index) + " is not configured");
  }
  const SimScene scene(cfg, limits);
  const SimLayer& layer = scene.targets()[static_cast<std::size_t>(target_index)];
  const config::SimTargetConfig& t = cfg.targets[static_cast<std::size_t>(target_index)];
  std::int32_t ox = 0, oy = 0;
  pattern_origin(t, limits, size_px, ox, oy);
  const double half = (size_px - 1) / 2.0;
  // rigid_only: the parts fixed to the pose point (jaw_dir 0), less every layer pixel a moving
  // part can cover at any opening the profile reaches (its PSF-blurred alpha slid along texture
  // y by up to max_abs, plus 1 px) — the pixels whose brightness depends on the pose alone.
  const int reach = rigid_only ? static_cast<int>(std::ceil(t.jaws.max_abs())) + 1 : 0;
  std::vector<std::uint8_t> moving_reach(static_cast<std::size_t>(layer.w()) * layer.h(), 0);
  for (const SimPart& part : layer.parts) {
    if (!rigid_only || part.jaw_dir == 0.0f) continue;
    for (int v = 0; v < layer.h(); ++v)
      for (int u = 0; u < layer.w(); ++u) {
        if (part.alpha.at(u, v) < 0.01f) continue;
        for (int dv = -reach; dv <= reach; ++dv)
          for (int du = -1; du <= 1; ++du) {
            const int uu = u + du, vv = v + dv;
            if (uu >= 0 && vv >= 0 && uu < layer.w() && vv < layer.h())
              moving_reach[static_cast<std::size_t>(vv) * layer.w() + uu] = 1;
          }
      }
  }
  Image img;
  img.width = img.height = size_px;
  img.bits = 8;
  img.pixels.assign(static_cast<std::size_t>(size_px) * size_px, 0);
  for (int y = 0; y < size_px; ++y) {
    for (int x = 0; x < size_px; ++x) {
      // The target at rest (φ = 0) centred on the crop: texture = layer centre + offset (as render()).
      const double u = layer.cx + (x - half), v = layer.cy + (y - half);
      if (!(u >= 0 && v >= 0 && u < layer.w() - 1 && v < layer.h() - 1)) continue;
      const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
      const double au = u - u0, av = v - v0;
      if (rigid_only && (moving_reach[static_cast<std::size_t>(v0) * layer.w() + u0] ||
                         moving_reach[static_cast<std::size_t>(v0 + 1) * layer.w() + u0 + 1]))
        continue;
      double a = 0;  // every part at rest (jaws at their configured start opening are not shifted here)
      for (const SimPart& part : layer.parts) {
        if (rigid_only && part.jaw_dir != 0.0f) continue;
        const FloatImage& A = part.alpha;
        a = std::max(a, (1 - au) * (1 - av) * A.at(u0, v0) + au * (1 - av) * A.at(u0 + 1, v0) +
                            (1 - au) * av * A.at(u0, v0 + 1) + au * av * A.at(u0 + 1, v0 + 1));
      }
      // The outline: alpha ≥ 0.5; the rigid part: every pixel it affects (its PSF-blurred
      // alpha ≥ 0.02), so that the edge against the background counts whole.
      if (a >= (rigid_only ? 0.02 : 0.5)) img.pixels[static_cast<std::size_t>(y) * size_px + x] = 255;
    }
  }
  return img;
}

}  // namespace sempose::hal
