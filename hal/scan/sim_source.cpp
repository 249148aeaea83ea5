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

// Bilinear sample with the coordinates clamped to the image (the scene continues like its
// border beyond the field, e.g. under drift).
inline float sample_clamped(const FloatImage& img, float x, float y) noexcept {
  x = std::clamp(x, 0.0f, static_cast<float>(img.w - 1));
  y = std::clamp(y, 0.0f, static_cast<float>(img.h - 1));
  const int x0 = std::min(static_cast<int>(x), img.w - 2 < 0 ? 0 : img.w - 2);
  const int y0 = std::min(static_cast<int>(y), img.h - 2 < 0 ? 0 : img.h - 2);
  const float ax = x - x0, ay = y - y0;
  const float* p = &img.v[static_cast<std::size_t>(y0) * img.w + x0];
  const float top = p[0] + ax * (p[1] - p[0]);
  const float bot = p[img.w] + ax * (p[img.w + 1] - p[img.w]);
  return top + ay * (bot - top);
}
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
  const auto& layers = scene_.targets();
  const std::size_t n_targets = layers.size();
  rng_.reseed(cfg.seed, seq);

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
  const double line_ns = static_cast<double>(roi.w) * dwell_ns + limits_.line_flyback_ns;
  const FloatImage& bg = scene_.background();
  const int lag_n = static_cast<int>(lag_px_.size());

  std::array<LinePose, kMaxTargets> pose{};
  for (int row = 0; row < roi.h; ++row) {
    // The beam scans this line at its own time: targets and drift are evaluated per line.
    const double t_line = seconds(t_start_ns) + (row * line_ns + 0.5 * roi.w * dwell_ns) * 1e-9;
    double dx = 0, dy = 0;
    drift_at(t_line, dx, dy);
    const double gain = 1.0 + cfg.brightness_drift * std::sin(kTwoPi * t_line / cfg.brightness_drift_period_s);
    const double jitter = cfg.noise ? cfg.line_jitter_px * rng_.normal() : 0.0;
    const float qy = static_cast<float>(roi.y + row - dy);
    for (std::size_t t = 0; t < n_targets; ++t) {
      pose[t].active = false;
      if (!layers[t].enabled) continue;
      const Pose2 p = trajectories_[t].at(t_line);
      if (std::fabs(qy - p.y_px) > layers[t].radius) continue;
      pose[t] = {true, p.x_px, p.y_px, std::cos(p.phi_deg * kDegToRad), std::sin(p.phi_deg * kDegToRad)};
    }
    Pixel* dst = out + static_cast<std::size_t>(row) * roi.w;
    const float qx0 = static_cast<float>(roi.x + jitter - dx);
    for (int i = 0; i < roi.w; ++i) {
      const float qx = qx0 + static_cast<float>(i) - (i < lag_n ? lag_px_[i] : 0.0f);
      float b = sample_clamped(bg, qx, qy);
      for (std::size_t t = 0; t < n_targets; ++t) {
        if (!pose[t].active) continue;
        const SimLayer& L = layers[t];
        // Inverse of the on-screen CCW rotation (README: Conventions): scene offset -> texture.
        const float X = qx - static_cast<float>(pose[t].cx), Y = qy - static_cast<float>(pose[t].cy);
        const float c = static_cast<float>(pose[t].c), s = static_cast<float>(pose[t].s);
        const float u = static_cast<float>(L.cx) + c * X - s * Y;
        const float v = static_cast<float>(L.cy) + s * X + c * Y;
        if (!(u >= 0.0f && v >= 0.0f && u < static_cast<float>(L.alpha.w - 1) && v < static_cast<float>(L.alpha.h - 1))) continue;
        const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
        const float au = u - u0, av = v - v0;
        const std::size_t o = static_cast<std::size_t>(v0) * L.alpha.w + u0;
        const float w00 = (1 - au) * (1 - av), w10 = au * (1 - av), w01 = (1 - au) * av, w11 = au * av;
        const float* A = &L.alpha.v[o];
        const float* P = &L.premul.v[o];
        const std::size_t st = static_cast<std::size_t>(L.alpha.w);
        const float a = w00 * A[0] + w10 * A[1] + w01 * A[st] + w11 * A[st + 1];
        const float pm = w00 * P[0] + w10 * P[1] + w01 * P[st] + w11 * P[st + 1];
        b = b * (1.0f - a) + pm;
      }
      const double mean_e = std::max(0.0, b * gain) * n_white;
      double e;
      if (noise) {
        // Detector cascade: Poisson electrons, each with a Gamma(k, 1/k) gain (mean 1):
        // their sum is Gamma(n·k)/k. Then Gaussian read noise.
        const std::uint32_t n = rng_.poisson(mean_e);
        e = n > 0 ? rng_.fast_gamma(n * k) * inv_k : 0.0;
        if (read_noise > 0) e += read_noise * rng_.fast_normal();
      } else {
        e = mean_e;
      }
      const double counts = offset_counts + e * counts_per_e;
      dst[i] = static_cast<Pixel>(counts <= 0.0 ? 0.0 : counts >= maxv ? maxv : counts);
    }
  }
  // Truth: each target's pose at mid-scan as it appears (drift included, jitter not).
  const double t_mid = seconds(t_start_ns) + 0.5 * static_cast<double>(limits_.scan_time_ns(roi.w, roi.h, dwell_ns)) * 1e-9;
  double dx = 0, dy = 0;
  drift_at(t_mid, dx, dy);
  for (std::size_t t = 0; t < n_targets && t < static_cast<std::size_t>(kMaxTargets); ++t) {
    const Pose2 p = trajectories_[t].at(t_mid);
    TargetTruth& tr = truth[t];
    tr.x_px = p.x_px + dx;
    tr.y_px = p.y_px + dy;
    tr.phi_deg = p.phi_deg;
    tr.present = layers[t].enabled && tr.x_px >= 0 && tr.y_px >= 0 && tr.x_px <= limits_.field_w - 1 &&
                 tr.y_px <= limits_.field_h - 1;
  }
  for (std::size_t t = n_targets; t < static_cast<std::size_t>(kMaxTargets); ++t) truth[t] = TargetTruth{};
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

Image render_sim_pattern_mask(const config::SimConfig& cfg, const ScanLimits& limits, int target_index, int size_px) {
  if (target_index < 0 || target_index >= static_cast<int>(cfg.targets.size())) {
    throw std::runtime_error("render_sim_pattern_mask: target " + std::to_string(target_index) + " is not configured");
  }
  const SimScene scene(cfg, limits);
  const SimLayer& layer = scene.targets()[static_cast<std::size_t>(target_index)];
  const config::SimTargetConfig& t = cfg.targets[static_cast<std::size_t>(target_index)];
  std::int32_t ox = 0, oy = 0;
  pattern_origin(t, limits, size_px, ox, oy);
  const double half = (size_px - 1) / 2.0;
  Image img;
  img.width = img.height = size_px;
  img.bits = 8;
  img.pixels.assign(static_cast<std::size_t>(size_px) * size_px, 0);
  for (int y = 0; y < size_px; ++y) {
    for (int x = 0; x < size_px; ++x) {
      // The target at rest (φ = 0) centred on the crop: texture = layer centre + offset (as render()).
      const double u = layer.cx + (x - half), v = layer.cy + (y - half);
      if (!(u >= 0 && v >= 0 && u < layer.alpha.w - 1 && v < layer.alpha.h - 1)) continue;
      const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
      const double au = u - u0, av = v - v0;
      const double a = (1 - au) * (1 - av) * layer.alpha.at(u0, v0) + au * (1 - av) * layer.alpha.at(u0 + 1, v0) +
                       (1 - au) * av * layer.alpha.at(u0, v0 + 1) + au * av * layer.alpha.at(u0 + 1, v0 + 1);
      if (a >= 0.5) img.pixels[static_cast<std::size_t>(y) * size_px + x] = 255;
    }
  }
  return img;
}

}  // namespace sempose::hal
