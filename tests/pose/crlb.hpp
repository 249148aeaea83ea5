// The Cramér–Rao lower bound on a single frame's pose θ = (x_px, y_px, φ_deg): the smallest
// covariance any unbiased estimator can reach from the pixels the tracker uses (its pattern
// mask, a circle of radius P/2 − inset centred on the target). Fisher information
//   F = Σ_mask J Jᵀ / var,   J = ∂λ/∂θ (λ: mean detected electrons of a pixel),
// J by central differences of noise-free renders at θ ± δ, var from the detector model:
//   var = λ·excess + read_noise²   (Poisson electrons × Gamma(k, 1/k) gain: excess = 1 + 1/k;
//                                   pure Poisson: excess = 1, read_noise = 0).
// The bound is C = F⁻¹. It assumes a known, noise-free template and no prior, so it is
// what a perfect single-frame estimator could reach; motion blur within the scan, drift,
// line jitter and the recorded pattern's own noise only add to it.
// Test/benchmark helper (allocates).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "sempose/config/tracker_config.hpp"
#include "sempose/hal/sim_source.hpp"
#include "sempose/pose/zncc.hpp"
#include "sim_harness.hpp"
#include "warp_scene.hpp"

namespace sempose::pose::testing {

struct Crlb {
  bool valid = false;                 // F finite and invertible (a flat scene has no bound)
  std::array<std::array<double, 3>, 3> fisher{};  // per px², px·deg, deg²
  std::array<std::array<double, 3>, 3> cov{};     // F⁻¹: px², px·deg, deg²
  int pixels = 0;                     // pixels summed (the mask)
  double var_pos_px2() const noexcept {
    return valid ? cov[0][0] + cov[1][1] : std::numeric_limits<double>::infinity();
  }
  double var_phi_deg2() const noexcept { return valid ? cov[2][2] : std::numeric_limits<double>::infinity(); }
  // 2-D position RMS bound √(C_xx + C_yy) and angle bound √C_φφ; +inf when there is none.
  double pos_rms_px() const noexcept { return std::sqrt(var_pos_px2()); }
  double phi_deg() const noexcept { return std::sqrt(var_phi_deg2()); }
  double sd_x_px() const noexcept { return valid ? std::sqrt(cov[0][0]) : std::numeric_limits<double>::infinity(); }
  double sd_y_px() const noexcept { return valid ? std::sqrt(cov[1][1]) : std::numeric_limits<double>::infinity(); }
};

struct CrlbNoise {
  double excess = 1.0;        // variance per electron: 1 + 1/k for the Gamma gain cascade
  double read_noise_e = 0.0;  // Gaussian read noise σ, electrons
};

struct CrlbStep {
  double pos_px = 0.05, phi_deg = 0.05;  // central-difference steps
};

// Symmetric 3×3 inverse by cofactors; false when F is singular (relative to its scale) or not finite.
inline bool invert_sym3(const std::array<std::array<double, 3>, 3>& a, std::array<std::array<double, 3>, 3>& inv) {
  const double c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
  const double c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2];
  const double c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
  const double det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02;
  // Singular when det is negligible against the product of the diagonal (scale-free test).
  const double scale = std::fabs(a[0][0] * a[1][1] * a[2][2]);
  if (!std::isfinite(det) || !(scale > 0) || !(det > 1e-12 * scale)) return false;
  inv[0][0] = c00 / det;
  inv[0][1] = inv[1][0] = c01 / det;
  inv[0][2] = inv[2][0] = c02 / det;
  inv[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) / det;
  inv[1][2] = inv[2][1] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) / det;
  inv[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) / det;
  for (const auto& r : inv)
    for (double v : r)
      if (!std::isfinite(v)) return false;
  return inv[0][0] > 0 && inv[1][1] > 0 && inv[2][2] > 0;
}

// The core: mean electrons λ and the renders at θ ± δ (plus[i], minus[i] for x, y, φ), all
// over the same n pixels; use[i] != 0 selects the pixels summed.
inline Crlb crlb_from_renders(const std::vector<double>& mean_e, const std::array<std::vector<double>, 3>& plus,
                              const std::array<std::vector<double>, 3>& minus, const std::array<double, 3>& step,
                              const std::vector<std::uint8_t>& use, const CrlbNoise& noise) {
  Crlb r;
  const double read2 = noise.read_noise_e * noise.read_noise_e;
  for (std::size_t i = 0; i < mean_e.size(); ++i) {
    if (!use[i]) continue;
    ++r.pixels;
    double j[3];
    for (int k = 0; k < 3; ++k) {
      // Differences at rounding level are no signal (a flat scene must have no bound).
      const double d = plus[k][i] - minus[k][i];
      j[k] = std::fabs(d) <= 1e-9 * std::max(std::fabs(plus[k][i]), std::fabs(minus[k][i])) ? 0.0 : d / (2 * step[k]);
    }
    if (j[0] == 0 && j[1] == 0 && j[2] == 0) continue;
    // λ → 0 without read noise: Poisson information J²/λ grows without bound; a floor keeps
    // it finite (such pixels are black and rare in SEM scenes).
    const double var = std::max(std::max(0.0, mean_e[i]) * noise.excess + read2, 1e-9);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) r.fisher[a][b] += j[a] * j[b] / var;
  }
  // A bound beyond 1000 px or 1000° means the pose is not observable from these pixels.
  r.valid = invert_sym3(r.fisher, r.cov) && r.cov[0][0] < 1e6 && r.cov[1][1] < 1e6 && r.cov[2][2] < 1e6;
  return r;
}

// The tracker's mask for a P×P pattern whose centre pixel ((P−1)/2, (P−1)/2) sits on the
// target: same radius and inset (2 + 2·prefilter_passes, as Tracker::Impl::mask_inset_px).
inline std::vector<std::uint8_t> tracker_mask(const config::TrackerConfig& tc) {
  const double inset = 2.0 + 2.0 * tc.prefilter_passes;  // copied from Tracker::Impl::mask_inset_px
  const PatternMask m(tc.pattern_size_px, tc.circular_mask, 8, inset);
  const int P = tc.pattern_size_px;
  std::vector<std::uint8_t> use(static_cast<std::size_t>(P) * P);
  for (int y = 0; y < P; ++y)
    for (int x = 0; x < P; ++x) use[static_cast<std::size_t>(y) * P + x] = m.inside(x, y) ? 1 : 0;
  return use;
}

// The P×P window whose centre pixel is the one nearest (x, y), as the tracker's integer
// displacement places the pattern.
inline hal::Roi mask_window(double x, double y, int P) {
  const double half = (P - 1) / 2.0;
  return {static_cast<std::int32_t>(std::lround(x - half)), static_cast<std::int32_t>(std::lround(y - half)), P, P};
}

// The simulator (config cfg, field fw×fh, dwell) with target 0 standing still at (x, y, φ):
// noise, drift, beam lag and brightness drift off (the renders are the expected electrons);
// the static background stays (its pixels do not move with θ, so they carry no pose
// information by themselves). Variance: the simulator's cascade, λ·(1 + 1/k) + read_noise².
// Each render builds its own SimSource (the trajectory is fixed at construction).
inline Crlb crlb_sim_config(config::SimConfig cfg, std::int32_t fw, std::int32_t fh, std::uint32_t dwell_ns,
                            const config::TrackerConfig& tc, double x, double y, double phi_deg, CrlbStep step = {}) {
  cfg.noise = false;
  cfg.drift.clear();
  cfg.beam_lag_px = 0;
  cfg.brightness_drift = 0;
  cfg.clock = "virtual";
  auto& t = cfg.targets[0];
  t.trajectory = config::TrajectoryConfig{};  // static
  const int P = tc.pattern_size_px;
  hal::ScanLimits lim;
  lim.field_w = fw;
  lim.field_h = fh;
  lim.max_roi_w = lim.max_roi_h = std::max(256, P);
  lim.bits = 16;  // fine output steps: the differences of δ-shifted renders are a few counts at 8 bits
  hal::Roi roi = mask_window(x, y, P);
  roi.x = std::clamp(roi.x, 0, fw - P);
  roi.y = std::clamp(roi.y, 0, fh - P);
  // Counts back to electrons as SimSource::render maps them (its + 0.5 only rounds).
  const double n_white = std::max(1e-9, cfg.electrons_per_pixel(dwell_ns));
  const double counts_per_e = cfg.output_white * lim.max_value() / n_white;
  const double offset_counts = cfg.output_offset * lim.max_value();
  const std::size_t n = static_cast<std::size_t>(P) * P;
  std::vector<hal::Pixel> px(n);
  hal::TargetTruth truth[hal::kMaxTargets];
  auto render = [&](double px_x, double px_y, double ph, std::vector<double>& out) {
    t.x_px = px_x;
    t.y_px = px_y;
    t.phi_deg = ph;
    hal::SimSource src(lim, cfg);
    src.render(roi, dwell_ns, hal::SimSource::kVirtualEpochNs, 0, px.data(), truth);
    out.resize(n);
    for (std::size_t i = 0; i < n; ++i) out[i] = (px[i] - offset_counts) / counts_per_e;
  };
  std::vector<double> mean_e;
  std::array<std::vector<double>, 3> plus, minus;
  render(x, y, phi_deg, mean_e);
  render(x + step.pos_px, y, phi_deg, plus[0]);
  render(x - step.pos_px, y, phi_deg, minus[0]);
  render(x, y + step.pos_px, phi_deg, plus[1]);
  render(x, y - step.pos_px, phi_deg, minus[1]);
  render(x, y, phi_deg + step.phi_deg, plus[2]);
  render(x, y, phi_deg - step.phi_deg, minus[2]);
  // The mask follows the target; the window may have been clamped at the field's edge.
  std::vector<std::uint8_t> use = tracker_mask(tc);
  const hal::Roi want = mask_window(x, y, P);
  if (want.x != roi.x || want.y != roi.y) {
    std::vector<std::uint8_t> moved(n, 0);
    for (int yy = 0; yy < P; ++yy)
      for (int xx = 0; xx < P; ++xx) {
        const int sx = xx + roi.x - want.x, sy = yy + roi.y - want.y;
        if (sx >= 0 && sy >= 0 && sx < P && sy < P)
          moved[static_cast<std::size_t>(yy) * P + xx] = use[static_cast<std::size_t>(sy) * P + sx];
      }
    use.swap(moved);
  }
  const CrlbNoise noise{1.0 + 1.0 / cfg.detector_gain_shape, cfg.read_noise_e};
  return crlb_from_renders(mean_e, plus, minus, {step.pos_px, step.pos_px, step.phi_deg}, use, noise);
}

// A benchmark scenario (make_sim_config, as SimHarness runs it) at the pose (x, y, φ).
inline Crlb crlb_sim(const Scenario& s, const config::TrackerConfig& tc, double x, double y, double phi_deg,
                     CrlbStep step = {}) {
  return crlb_sim_config(make_sim_config(s), s.field_w, s.field_h, s.dwell_ns, tc, x, y, phi_deg, step);
}

// WarpScene: scene point (cx, cy) shown at (x, y) turned by φ, pure Poisson at dose_e electrons
// per pixel at brightness 1 (λ = brightness·dose, as WarpScene::render draws it). The scene is
// sampled in double (WarpScene::sample) rather than through render()'s 16-bit levels; the
// pixel → scene mapping is copied from WarpScene::render.
inline Crlb crlb_warp(const WarpScene& scene, double cx, double cy, const config::TrackerConfig& tc, double x,
                      double y, double phi_deg, double dose_e, CrlbStep step = {}) {
  const int P = tc.pattern_size_px;
  const hal::Roi roi = mask_window(x, y, P);
  const std::size_t n = static_cast<std::size_t>(P) * P;
  auto render = [&](double tx, double ty, double ph, std::vector<double>& out) {
    out.resize(n);
    const double rad = ph * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
    for (int py = 0; py < P; ++py)
      for (int pxi = 0; pxi < P; ++pxi) {
        const double dx = roi.x + pxi - tx, dy = roi.y + py - ty;
        const double b = scene.sample(cx + dx * cs - dy * sn, cy + dx * sn + dy * cs);
        out[static_cast<std::size_t>(py) * P + pxi] = std::max(0.0, b) * dose_e;
      }
  };
  std::vector<double> mean_e;
  std::array<std::vector<double>, 3> plus, minus;
  render(x, y, phi_deg, mean_e);
  render(x + step.pos_px, y, phi_deg, plus[0]);
  render(x - step.pos_px, y, phi_deg, minus[0]);
  render(x, y + step.pos_px, phi_deg, plus[1]);
  render(x, y - step.pos_px, phi_deg, minus[1]);
  render(x, y, phi_deg + step.phi_deg, plus[2]);
  render(x, y, phi_deg - step.phi_deg, minus[2]);
  return crlb_from_renders(mean_e, plus, minus, {step.pos_px, step.pos_px, step.phi_deg}, tracker_mask(tc), CrlbNoise{});
}

// Mean of several bounds' variances (the bound along a run: poses differ a little in angle and
// background); invalid if any is.
struct CrlbMean {
  double var_pos_px2 = 0, var_phi_deg2 = 0;
  int n = 0;
  bool valid = true;
  void add(const Crlb& c) {
    valid = valid && c.valid;
    var_pos_px2 += c.var_pos_px2();
    var_phi_deg2 += c.var_phi_deg2();
    ++n;
  }
  double pos_rms_px() const { return valid && n ? std::sqrt(var_pos_px2 / n) : std::numeric_limits<double>::infinity(); }
  double phi_deg() const { return valid && n ? std::sqrt(var_phi_deg2 / n) : std::numeric_limits<double>::infinity(); }
};

}  // namespace sempose::pose::testing
