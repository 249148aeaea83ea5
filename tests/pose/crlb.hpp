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
#include "sempose/pose/pattern_support.hpp"
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

// The simulator's expected electrons of one ROI with target 0 at any pose, from a SimScene
// built once (building it — texture load, PSF blur — takes ~40 ms, a render ~1 ms): the
// compositing lines of SimSource::render copied (hal/scan/sim_source.cpp, float arithmetic
// kept) with noise, jitter, drift, beam lag and brightness drift off; only target 0 is drawn
// (make_sim_config disables the others). test_crlb checks it against SimSource::render.
class SimMeanRenderer {
 public:
  SimMeanRenderer(const config::SimConfig& cfg, std::int32_t fw, std::int32_t fh, std::uint32_t dwell_ns)
      : scene_(cfg, limits(fw, fh)),
        n_white_(std::max(1e-9, cfg.electrons_per_pixel(dwell_ns))),
        excess_(1.0 + 1.0 / cfg.detector_gain_shape),
        read_noise_e_(cfg.read_noise_e) {}
  CrlbNoise noise() const noexcept { return {excess_, read_noise_e_}; }

  void render(const hal::Roi& roi, double x, double y, double phi_deg, std::vector<double>& out) const {
    out.resize(static_cast<std::size_t>(roi.w) * roi.h);
    const hal::FloatImage& bg = scene_.background();
    const hal::SimLayer& L = scene_.targets()[0];
    const double rad = phi_deg * (6.283185307179586 / 360.0);
    const float c = static_cast<float>(std::cos(rad)), s = static_cast<float>(std::sin(rad));
    for (int row = 0; row < roi.h; ++row) {
      const float qy = static_cast<float>(roi.y + row);
      const bool active = L.enabled && std::fabs(qy - y) <= L.radius;
      const float qx0 = static_cast<float>(roi.x);
      for (int i = 0; i < roi.w; ++i) {
        const float qx = qx0 + static_cast<float>(i);
        float b = sample_clamped(bg, qx, qy);
        if (active) {
          const float X = qx - static_cast<float>(x), Y = qy - static_cast<float>(y);
          const float u = static_cast<float>(L.cx) + c * X - s * Y;
          const float v = static_cast<float>(L.cy) + s * X + c * Y;
          if (u >= 0.0f && v >= 0.0f && u < static_cast<float>(L.alpha.w - 1) && v < static_cast<float>(L.alpha.h - 1)) {
            const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
            const float au = u - u0, av = v - v0;
            const std::size_t o = static_cast<std::size_t>(v0) * L.alpha.w + u0;
            const float w00 = (1 - au) * (1 - av), w10 = au * (1 - av), w01 = (1 - au) * av, w11 = au * av;
            const float* A = &L.alpha.v[o];
            const float* P = &L.premul.v[o];
            const std::size_t st = static_cast<std::size_t>(L.alpha.w);
            const float al = w00 * A[0] + w10 * A[1] + w01 * A[st] + w11 * A[st + 1];
            const float pm = w00 * P[0] + w10 * P[1] + w01 * P[st] + w11 * P[st + 1];
            b = b * (1.0f - al) + pm;
          }
        }
        out[static_cast<std::size_t>(row) * roi.w + i] = std::max(0.0, static_cast<double>(b)) * n_white_;
      }
    }
  }

 private:
  static hal::ScanLimits limits(std::int32_t fw, std::int32_t fh) {
    hal::ScanLimits lim;
    lim.field_w = fw;
    lim.field_h = fh;
    return lim;
  }
  // Copied from sim_source.cpp (file-local there): bilinear, coordinates clamped to the image.
  static float sample_clamped(const hal::FloatImage& img, float x, float y) noexcept {
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

  hal::SimScene scene_;
  double n_white_, excess_, read_noise_e_;
};

// The bound for the simulator's target 0 standing still at (x, y, φ) in field fw×fh: the static
// background stays (its pixels do not move with θ, so they carry no pose information by
// themselves). Variance: the simulator's cascade, λ·(1 + 1/k) + read_noise².
inline Crlb crlb_sim(const SimMeanRenderer& sim, std::int32_t fw, std::int32_t fh, const config::TrackerConfig& tc,
                     double x, double y, double phi_deg, CrlbStep step = {}) {
  const int P = tc.pattern_size_px;
  hal::Roi roi = mask_window(x, y, P);
  roi.x = std::clamp(roi.x, 0, fw - P);
  roi.y = std::clamp(roi.y, 0, fh - P);
  const std::size_t n = static_cast<std::size_t>(P) * P;
  std::vector<double> mean_e;
  std::array<std::vector<double>, 3> plus, minus;
  sim.render(roi, x, y, phi_deg, mean_e);
  sim.render(roi, x + step.pos_px, y, phi_deg, plus[0]);
  sim.render(roi, x - step.pos_px, y, phi_deg, minus[0]);
  sim.render(roi, x, y + step.pos_px, phi_deg, plus[1]);
  sim.render(roi, x, y - step.pos_px, phi_deg, minus[1]);
  sim.render(roi, x, y, phi_deg + step.phi_deg, plus[2]);
  sim.render(roi, x, y, phi_deg - step.phi_deg, minus[2]);
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
  return crlb_from_renders(mean_e, plus, minus, {step.pos_px, step.pos_px, step.phi_deg}, use, sim.noise());
}

// One-off form (builds the scene): config cfg, field fw×fh, dwell.
inline Crlb crlb_sim_config(const config::SimConfig& cfg, std::int32_t fw, std::int32_t fh, std::uint32_t dwell_ns,
                            const config::TrackerConfig& tc, double x, double y, double phi_deg, CrlbStep step = {}) {
  return crlb_sim(SimMeanRenderer(cfg, fw, fh, dwell_ns), fw, fh, tc, x, y, phi_deg, step);
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
