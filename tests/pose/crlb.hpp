// The Cramér–Rao lower bound on a single frame's pose (x_px, y_px, φ_deg): the smallest
// covariance any unbiased estimator can reach from every pixel the target affects.
//   λ_i = D·(g·b_i(θ) + o)                mean detected electrons of pixel i
//   F   = Σ_support J Jᵀ / var,  J = ∂λ/∂(x, y, φ, [scale], [jaw opening], g, o)
//   var = λ·excess + read_noise²         (Poisson electrons × Gamma(k, 1/k) gain: excess = 1 + 1/k;
//                                         pure Poisson: excess = 1, read_noise = 0)
// b_i(θ) is the noise-free render (the simulator's own SimScene::render_mean, or the warped
// real SEM scene), D the electrons per pixel at brightness 1, g and o the photometric gain and
// offset. Gain and offset are always nuisance parameters (a frame's contrast and brightness
// are unknown: charging, detector drift); scale and the jaws' opening are too where they vary.
// The pose block of C = F⁻¹ is the bound: nuisances can only raise it (they take information
// the pose would otherwise use). The support is the target's blurred footprint (its coverage
// > 1e-3 after PSF and defocus), not the tracker's mask: every pixel the target changes.
// It assumes a known, noise-free appearance and no prior, so it is what a perfect
// single-frame estimator could reach; motion within the scan, drift, line jitter, the
// detector's low-pass (an invertible filter: no information lost) and the recorded pattern's
// own noise are not in it. Test/benchmark helper (allocates).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "sempose/config/tracker_config.hpp"
#include "sempose/hal/sim_source.hpp"
#include "sim_harness.hpp"
#include "warp_scene.hpp"

namespace sempose::pose::testing {

constexpr int kCrlbMaxParams = 7;  // x, y, φ, scale, jaw, gain, offset
using CrlbMatrix = std::array<std::array<double, kCrlbMaxParams>, kCrlbMaxParams>;

struct Crlb {
  bool valid = false;  // F finite and invertible (a flat scene has no bound)
  int n_params = 0;    // 3 pose parameters first, then the nuisances
  CrlbMatrix fisher{};  // per px², px·deg, deg², ...
  CrlbMatrix cov{};     // F⁻¹
  int pixels = 0;       // pixels summed (the support)
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
  double pos_px = 0.05, phi_deg = 0.05, scale = 0.002, jaw_px = 0.05;  // central-difference steps
};

// Which nuisance parameters are estimated with the pose.
struct CrlbNuisance {
  bool photometric = true;  // gain and offset
  bool scale = false;       // where the scale varies
  bool jaws = false;        // where the gripper's jaws move
};

// Inverse of a symmetric positive definite n×n matrix: Eigen's Cholesky (LLT) on the matrix
// scaled to unit diagonal, so the singularity test is scale-free; false when singular or not
// finite. (Benchmark code: Eigen's dynamic matrices may allocate; the RT fit keeps its own
// fixed 6×6 solve.)
inline bool invert_spd(const CrlbMatrix& a, int n, CrlbMatrix& inv) {
  Eigen::VectorXd d(n);
  for (int i = 0; i < n; ++i) {
    if (!(a[i][i] > 0) || !std::isfinite(a[i][i])) return false;
    d[i] = 1.0 / std::sqrt(a[i][i]);
  }
  Eigen::MatrixXd r(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) r(i, j) = a[i][j] * d[i] * d[j];
  const Eigen::LLT<Eigen::MatrixXd> llt(r);
  // (Near) linearly dependent parameters: a pivot of the unit-diagonal matrix at ~0.
  if (llt.info() != Eigen::Success || !(llt.matrixL().toDenseMatrix().diagonal().minCoeff() > 1e-6)) return false;
  const Eigen::MatrixXd ri = llt.solve(Eigen::MatrixXd::Identity(n, n));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      inv[i][j] = ri(i, j) * d[i] * d[j];
      if (!std::isfinite(inv[i][j])) return false;
    }
  return true;
}

// The core: mean electrons λ and the derivatives ∂λ/∂θ_k (one vector per parameter, the pose's
// three first) over the same pixels; use[i] != 0 selects the pixels summed.
inline Crlb crlb_from_jacobian(const std::vector<double>& mean_e, const std::vector<std::vector<double>>& jac,
                               const std::vector<std::uint8_t>& use, const CrlbNoise& noise) {
  Crlb r;
  r.n_params = static_cast<int>(jac.size());
  const int n = r.n_params;
  const double read2 = noise.read_noise_e * noise.read_noise_e;
  for (std::size_t i = 0; i < mean_e.size(); ++i) {
    if (!use[i]) continue;
    ++r.pixels;
    // λ → 0 without read noise: Poisson information J²/λ grows without bound; a floor keeps
    // it finite (such pixels are black and rare in SEM scenes).
    const double var = std::max(std::max(0.0, mean_e[i]) * noise.excess + read2, 1e-9);
    for (int a = 0; a < n; ++a) {
      const double ja = jac[static_cast<std::size_t>(a)][i];
      if (ja == 0) continue;
      for (int b = 0; b < n; ++b) r.fisher[a][b] += ja * jac[static_cast<std::size_t>(b)][i] / var;
    }
  }
  // A bound beyond 1000 px or 1000° means the pose is not observable from these pixels.
  r.valid = n >= 3 && invert_spd(r.fisher, n, r.cov) && r.cov[0][0] > 0 && r.cov[1][1] > 0 && r.cov[2][2] > 0 &&
            r.cov[0][0] < 1e6 && r.cov[1][1] < 1e6 && r.cov[2][2] < 1e6;
  return r;
}

// Central difference (plus − minus)/(2·step), zero where the difference is at rounding level
// (a flat scene must have no bound).
inline std::vector<double> central_difference(const std::vector<double>& plus, const std::vector<double>& minus, double step) {
  std::vector<double> d(plus.size());
  for (std::size_t i = 0; i < plus.size(); ++i) {
    const double diff = plus[i] - minus[i];
    d[i] = std::fabs(diff) <= 1e-9 * std::max(std::fabs(plus[i]), std::fabs(minus[i])) ? 0.0 : diff / (2 * step);
  }
  return d;
}

// The state of target 0 of a simulated frame: pose, shape and the frame's photometry.
struct SimState {
  double x = 0, y = 0, phi_deg = 0, scale = 1, jaw_px = 0;
  double gain = 1, offset = 0;  // brightness b -> gain·b + offset
  double defocus_px = 0;        // extra PSF σ
};

// The simulator's noise-free render of target 0 (make_sim_config leaves the others off), from
// a SimScene built once (texture load and PSF blur ~40 ms; a render ~1 ms): SimScene::render_mean,
// the same compositing SimSource::render uses.
class SimMeanRenderer {
 public:
  SimMeanRenderer(const config::SimConfig& cfg, std::int32_t fw, std::int32_t fh, std::uint32_t dwell_ns)
      : scene_(cfg, limits(fw, fh)),
        n_white_(std::max(1e-9, cfg.electrons_per_pixel(dwell_ns))),
        excess_(1.0 + 1.0 / cfg.detector_gain_shape),
        read_noise_e_(cfg.read_noise_e),
        fw_(fw),
        fh_(fh) {}
  CrlbNoise noise() const noexcept { return {excess_, read_noise_e_}; }
  double electrons_per_unit() const noexcept { return n_white_; }
  const hal::SimScene& scene() const noexcept { return scene_; }
  std::int32_t field_w() const noexcept { return fw_; }
  std::int32_t field_h() const noexcept { return fh_; }

  // Brightness b (gain 1, offset 0) of roi with target 0 in state s; coverage optional.
  void render(const hal::Roi& roi, const SimState& s, std::vector<double>& b, std::vector<float>* coverage = nullptr) const {
    std::vector<hal::SimTargetPose> poses(scene_.targets().size());
    for (auto& p : poses) p.active = false;
    if (!poses.empty()) poses[0] = {true, s.x, s.y, s.phi_deg, s.scale, s.jaw_px};
    std::vector<float> f;
    scene_.render_mean(roi, poses.data(), 1.0, 0.0, s.defocus_px, f, coverage);
    b.assign(f.begin(), f.end());
  }
  // The window holding everything target 0 can affect in state s (clamped to the field).
  hal::Roi support_window(const SimState& s) const {
    const hal::SimLayer& L = scene_.targets()[0];
    const double r = L.radius * std::max(1.0, s.scale) + std::fabs(s.jaw_px) + 3.0 * s.defocus_px + 3;
    const int x0 = std::max(0, static_cast<int>(std::floor(s.x - r))), y0 = std::max(0, static_cast<int>(std::floor(s.y - r)));
    const int x1 = std::min(fw_ - 1, static_cast<int>(std::ceil(s.x + r))), y1 = std::min(fh_ - 1, static_cast<int>(std::ceil(s.y + r)));
    return {x0, y0, std::max(0, x1 - x0 + 1), std::max(0, y1 - y0 + 1)};
  }

 private:
  static hal::ScanLimits limits(std::int32_t fw, std::int32_t fh) {
    hal::ScanLimits lim;
    lim.field_w = fw;
    lim.field_h = fh;
    return lim;
  }
  hal::SimScene scene_;
  double n_white_, excess_, read_noise_e_;
  std::int32_t fw_, fh_;
};

// The bound for the simulator's target 0 in state s (the static background stays: its pixels
// do not move with θ, so they carry no pose information by themselves). Variance: the
// simulator's cascade, λ·(1 + 1/k) + read_noise².
// rigid_only_reach_px > 0: only the pixels the gripper's jaws leave unchanged at every opening
// within ±that (the bound of an estimator that masks the jaws out: a shape mask of the body).
inline Crlb crlb_sim(const SimMeanRenderer& sim, const SimState& s, CrlbNuisance nu = {}, CrlbStep step = {},
                     double rigid_only_reach_px = 0) {
  const hal::Roi roi = sim.support_window(s);
  const double D = sim.electrons_per_unit();
  std::vector<double> b, p, m;
  std::vector<float> cover;
  sim.render(roi, s, b, &cover);
  std::vector<std::uint8_t> use(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) use[i] = cover[i] > 1e-3f;
  for (int k = -4; rigid_only_reach_px > 0 && k <= 4; ++k) {
    SimState o = s;
    o.jaw_px = rigid_only_reach_px * k / 4.0;
    sim.render(roi, o, p);
    for (std::size_t i = 0; i < b.size(); ++i)
      if (std::fabs(p[i] - b[i]) > 1e-4) use[i] = 0;
  }
  std::vector<double> mean_e(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) mean_e[i] = D * std::max(0.0, s.gain * b[i] + s.offset);
  std::vector<std::vector<double>> jac;
  auto derivative = [&](SimState hi, SimState lo, double h) {
    sim.render(roi, hi, p);
    sim.render(roi, lo, m);
    std::vector<double> d = central_difference(p, m, h);
    for (double& v : d) v *= D * s.gain;
    jac.push_back(std::move(d));
  };
  SimState a = s, z = s;
  a.x += step.pos_px, z.x -= step.pos_px;
  derivative(a, z, step.pos_px);
  a = s, z = s;
  a.y += step.pos_px, z.y -= step.pos_px;
  derivative(a, z, step.pos_px);
  a = s, z = s;
  a.phi_deg += step.phi_deg, z.phi_deg -= step.phi_deg;
  derivative(a, z, step.phi_deg);
  if (nu.scale) {
    a = s, z = s;
    a.scale += step.scale, z.scale -= step.scale;
    derivative(a, z, step.scale);
  }
  if (nu.jaws) {
    a = s, z = s;
    a.jaw_px += step.jaw_px, z.jaw_px -= step.jaw_px;
    derivative(a, z, step.jaw_px);
  }
  if (nu.photometric) {
    std::vector<double> dg(b.size()), doff(b.size(), D);
    for (std::size_t i = 0; i < b.size(); ++i) dg[i] = D * b[i];
    jac.push_back(std::move(dg));
    jac.push_back(std::move(doff));
  }
  return crlb_from_jacobian(mean_e, jac, use, sim.noise());
}

// One-off form (builds the scene): config cfg, field fw×fh, dwell, target at rest at (x, y, φ).
inline Crlb crlb_sim_config(const config::SimConfig& cfg, std::int32_t fw, std::int32_t fh, std::uint32_t dwell_ns,
                            double x, double y, double phi_deg, CrlbNuisance nu = {}) {
  SimState s;
  s.x = x, s.y = y, s.phi_deg = phi_deg;
  return crlb_sim(SimMeanRenderer(cfg, fw, fh, dwell_ns), s, nu);
}

// WarpScene: scene point (cx, cy) shown at (x, y) turned by φ, pure Poisson at dose_e electrons
// per pixel at brightness 1 (λ = dose·(g·b + o), g = 1, o = 0, as WarpScene::render draws it).
// The whole scene moves rigidly (a stage move), so the target is the recorded crop: the
// support is the P×P pattern's footprint, turned with it. The scene is sampled in double
// (WarpScene::sample) rather than through render()'s 16-bit levels; the pixel -> scene mapping
// is WarpScene::render's.
inline Crlb crlb_warp(const WarpScene& scene, double cx, double cy, int P, double x, double y, double phi_deg,
                      double dose_e, CrlbNuisance nu = {}, CrlbStep step = {}) {
  const double half = P / 2.0, reach = half * std::sqrt(2.0) + 2;
  const hal::Roi roi{static_cast<std::int32_t>(std::floor(x - reach)), static_cast<std::int32_t>(std::floor(y - reach)),
                     static_cast<std::int32_t>(2 * reach + 2), static_cast<std::int32_t>(2 * reach + 2)};
  const std::size_t n = static_cast<std::size_t>(roi.w) * roi.h;
  auto render = [&](double tx, double ty, double ph, std::vector<double>& out, std::vector<std::uint8_t>* use) {
    out.resize(n);
    if (use) use->assign(n, 0);
    const double rad = ph * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
    for (int py = 0; py < roi.h; ++py)
      for (int pxi = 0; pxi < roi.w; ++pxi) {
        const double dx = roi.x + pxi - tx, dy = roi.y + py - ty;
        const double u = dx * cs - dy * sn, v = dx * sn + dy * cs;
        const std::size_t i = static_cast<std::size_t>(py) * roi.w + pxi;
        out[i] = std::max(0.0, scene.sample(cx + u, cy + v));
        if (use) (*use)[i] = std::fabs(u) <= half && std::fabs(v) <= half;
      }
  };
  std::vector<double> b, p, m;
  std::vector<std::uint8_t> use;
  render(x, y, phi_deg, b, &use);
  std::vector<std::vector<double>> jac;
  auto derivative = [&](double x1, double y1, double f1, double x0, double y0, double f0, double h) {
    render(x1, y1, f1, p, nullptr);
    render(x0, y0, f0, m, nullptr);
    std::vector<double> d = central_difference(p, m, h);
    for (double& v : d) v *= dose_e;
    jac.push_back(std::move(d));
  };
  derivative(x + step.pos_px, y, phi_deg, x - step.pos_px, y, phi_deg, step.pos_px);
  derivative(x, y + step.pos_px, phi_deg, x, y - step.pos_px, phi_deg, step.pos_px);
  derivative(x, y, phi_deg + step.phi_deg, x, y, phi_deg - step.phi_deg, step.phi_deg);
  if (nu.photometric) {
    std::vector<double> dg(n), doff(n, dose_e);
    for (std::size_t i = 0; i < n; ++i) dg[i] = dose_e * b[i];
    jac.push_back(std::move(dg));
    jac.push_back(std::move(doff));
  }
  std::vector<double> mean_e(n);
  for (std::size_t i = 0; i < n; ++i) mean_e[i] = dose_e * b[i];
  return crlb_from_jacobian(mean_e, jac, use, CrlbNoise{});
}

// Mean of several bounds' variances (the bound along a run: poses differ in angle, scale and
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
