// Two maximum-likelihood oracles for the accuracy benchmark's --decompose mode: what the best
// single-frame estimator reaches on frames drawn from exactly the noise model the bound
// (crlb.hpp) assumes, started at the truth, weighted by the true per-pixel variance.
//   exact:   the model is the scene itself (the simulator's noise-free render of target 0 at
//            the candidate state, background included; or the warped real scene), with gain
//            and offset (and scale / jaws where the bound has them as nuisances). Over the
//            bound's own pixels. This is the check on the bound: its RMS / bound must come out
//            near 1.0 (above it by the nonlinearity and the finite draws only).
//   pattern: what any tracker that knows only the recorded pattern can do: the recorded
//            pattern (background of the place it was recorded and the recording's noise
//            included) warped by a similarity (x, y, φ, scale where it varies), with gain and
//            offset, over sempose's pixels (the circle of radius zone_r·scale about the pose).
// Both are Gauss–Newton on the weighted squared residual (the Gaussian approximation of the
// likelihood at these doses), a fixed number of iterations, numeric Jacobians for the pose
// and analytic ones for gain/offset. Iterations: the exact fit converges in 3 (4 allowed, its
// Jacobian from the truth reused: a fixed-Jacobian Gauss–Newton, same minimum); the
// pattern fit's minimum lies along a shallow valley away from the truth and needs ~50
// (measured, lamella_post smooth dose 20, its bias in angle: 3.0x the bound after 3, 6.9x after 8,
// 11.9x after 20, 14.0x after 50, 14.4x after 100): it gets 60, stopping once a step is < 1e-4. Frames: at each state, fresh draws of the simulator's
// cascade (Poisson electrons × Gamma(k, 1/k) gain + Gaussian read noise) or pure Poisson for
// the warped scene — no quantisation, no motion within the scan, no drift: the bound's model.
// Benchmark helper (allocates freely).
#pragma once

#include <array>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "crlb.hpp"

namespace sempose::pose::testing {

// A pose-parameter vector for the oracles: x, y, φ, scale, jaw (the last two used when fitted).
struct OraclePose {
  double x = 0, y = 0, phi_deg = 0, scale = 1, jaw_px = 0;
};

// Errors of one fit (pose only): 2-D position and angle.
struct OracleError {
  double dpos2 = 0, dphi = 0;
  bool ok = false;  // converged to a finite pose
};

// Weighted Gauss–Newton of model(pose)·g + o to data y over the pixels in `use`, weights 1/var.
// model(p, out) renders the noise-free model (any unit) over the frame's pixels; the fit
// starts at `start` with g, o from the weighted linear fit there. Fitted: x, y, φ, and scale
// and/or the jaws' opening when asked.
inline OracleError fit_ml(const std::function<void(const OraclePose&, std::vector<double>&)>& model, const std::vector<double>& y,
                          const std::vector<double>& var, const std::vector<std::uint8_t>& use, const OraclePose& start,
                          const OraclePose& truth, bool fit_scale, bool fit_jaw, int iterations,
                          std::vector<std::vector<double>>* jacobian_cache = nullptr) {
  std::array<int, 5> which{0, 1, 2, 0, 0};  // parameter k of the fit -> OraclePose member
  int n_pose = 3;
  if (fit_scale) which[static_cast<std::size_t>(n_pose++)] = 3;
  if (fit_jaw) which[static_cast<std::size_t>(n_pose++)] = 4;
  const std::size_t n = y.size();
  const int np = n_pose + 2;
  OraclePose p = start;
  std::vector<double> m0, mp, mm;
  const std::array<double, 5> h{0.05, 0.05, 0.05, 0.002, 0.05};
  auto bump = [&which](OraclePose q, int kk, double d) {
    const int k = which[static_cast<std::size_t>(kk)];
    if (k == 0) q.x += d;
    else if (k == 1) q.y += d;
    else if (k == 2) q.phi_deg += d;
    else if (k == 3) q.scale += d;
    else q.jaw_px += d;
    return q;
  };
  double g = 1, o = 0;
  std::vector<std::vector<double>> J(static_cast<std::size_t>(n_pose), std::vector<double>(n));
  for (int it = 0; it < iterations; ++it) {
    model(p, m0);
    if (it == 0) {  // gain and offset: weighted linear least squares at the start pose
      double sw = 0, sm = 0, sy = 0, smm = 0, smy = 0;
      for (std::size_t i = 0; i < n; ++i) {
        if (!use[i]) continue;
        const double w = 1 / var[i];
        sw += w, sm += w * m0[i], sy += w * y[i], smm += w * m0[i] * m0[i], smy += w * m0[i] * y[i];
      }
      const double det = sw * smm - sm * sm;
      if (!(std::fabs(det) > 0)) return {};
      g = (sw * smy - sm * sy) / det;
      o = (sy - g * sm) / sw;
    }
    // jacobian_cache: the model's pose derivatives at the start, computed once and reused over
    // the iterations and over every fit that starts there (the exact oracle: its renders are
    // the cost; at these noise levels the fit moves by a fraction of the steps' scale).
    const bool cached = jacobian_cache && !jacobian_cache->empty();
    if (jacobian_cache && cached) {
      for (int k = 0; k < n_pose; ++k)
        for (std::size_t i = 0; i < n; ++i) J[static_cast<std::size_t>(k)][i] = g * (*jacobian_cache)[static_cast<std::size_t>(k)][i];
    }
    for (int k = 0; k < n_pose && !cached; ++k) {
      model(bump(p, k, h[static_cast<std::size_t>(which[static_cast<std::size_t>(k)])]), mp);
      model(bump(p, k, -h[static_cast<std::size_t>(which[static_cast<std::size_t>(k)])]), mm);
      for (std::size_t i = 0; i < n; ++i) J[static_cast<std::size_t>(k)][i] = g * (mp[i] - mm[i]) / (2 * h[static_cast<std::size_t>(which[static_cast<std::size_t>(k)])]);
      if (jacobian_cache) {
        jacobian_cache->resize(static_cast<std::size_t>(n_pose));
        (*jacobian_cache)[static_cast<std::size_t>(k)].resize(n);
        for (std::size_t i = 0; i < n; ++i) (*jacobian_cache)[static_cast<std::size_t>(k)][i] = J[static_cast<std::size_t>(k)][i] / g;
      }
    }
    CrlbMatrix A{};
    std::array<double, kCrlbMaxParams> b{};
    std::array<double, kCrlbMaxParams> jr{};
    for (std::size_t i = 0; i < n; ++i) {
      if (!use[i]) continue;
      for (int k = 0; k < n_pose; ++k) jr[static_cast<std::size_t>(k)] = J[static_cast<std::size_t>(k)][i];
      jr[static_cast<std::size_t>(n_pose)] = m0[i];
      jr[static_cast<std::size_t>(n_pose + 1)] = 1.0;
      const double w = 1 / var[i], r = y[i] - (g * m0[i] + o);
      for (int a = 0; a < np; ++a) {
        b[static_cast<std::size_t>(a)] += w * jr[static_cast<std::size_t>(a)] * r;
        for (int c = 0; c < np; ++c) A[a][c] += w * jr[static_cast<std::size_t>(a)] * jr[static_cast<std::size_t>(c)];
      }
    }
    CrlbMatrix Ai{};
    if (!invert_spd(A, np, Ai)) return {};
    std::array<double, kCrlbMaxParams> d{};
    for (int a = 0; a < np; ++a)
      for (int c = 0; c < np; ++c) d[static_cast<std::size_t>(a)] += Ai[a][c] * b[static_cast<std::size_t>(c)];
    for (int k = 0; k < n_pose; ++k) p = bump(p, k, d[static_cast<std::size_t>(k)]);
    g += d[static_cast<std::size_t>(n_pose)];
    o += d[static_cast<std::size_t>(n_pose + 1)];
    if (std::fabs(d[0]) + std::fabs(d[1]) + std::fabs(d[2]) < 1e-4) break;  // converged
  }
  OracleError e;
  const double dx = p.x - truth.x, dy = p.y - truth.y;
  e.dpos2 = dx * dx + dy * dy;
  e.dphi = std::fmod(p.phi_deg - truth.phi_deg + 540.0, 360.0) - 180.0;
  e.ok = std::isfinite(e.dpos2) && std::isfinite(e.dphi) && e.dpos2 < 9.0 && std::fabs(e.dphi) < 10.0;
  return e;
}

// The recorded pattern as a continuous image: Keys bicubic (a = −0.5) on its grey levels;
// pattern pixel ((P−1)/2, (P−1)/2) is the pose point (render_sim_pattern's and WarpScene's convention).
class PatternModel {
 public:
  explicit PatternModel(const hal::Image& im) : w_(im.width), h_(im.height), v_(im.pixels.begin(), im.pixels.end()) {}
  double sample(double x, double y) const {
    const int ix = static_cast<int>(std::floor(x)), iy = static_cast<int>(std::floor(y));
    const double fx = x - ix, fy = y - iy;
    double wx[4], wy[4];
    keys(fx, wx);
    keys(fy, wy);
    double acc = 0;
    for (int j = 0; j < 4; ++j) {
      double row = 0;
      for (int i = 0; i < 4; ++i) row += wx[i] * at(ix - 1 + i, iy - 1 + j);
      acc += wy[j] * row;
    }
    return acc;
  }
  // Frame pixel (qx, qy) for the target at pose p: pattern coordinates through the inverse of
  // the on-screen CCW rotation and the scale (SimScene::line_pose's field -> texture mapping).
  double at_frame(double qx, double qy, const OraclePose& p) const {
    const double c = std::cos(p.phi_deg * M_PI / 180) / p.scale, s = std::sin(p.phi_deg * M_PI / 180) / p.scale;
    const double X = qx - p.x, Y = qy - p.y, half = (w_ - 1) / 2.0;
    return sample(half + c * X - s * Y, half + s * X + c * Y);
  }
  int size() const { return w_; }

 private:
  static void keys(double t, double* w) {
    const double a = -0.5, t2 = t * t, t3 = t2 * t;
    w[0] = a * (t3 - 2 * t2 + t);
    w[1] = (a + 2) * t3 - (a + 3) * t2 + 1;
    w[2] = -(a + 2) * t3 + (2 * a + 3) * t2 - a * t;
    w[3] = -a * (t3 - t2);
  }
  double at(int x, int y) const {
    x = std::clamp(x, 0, w_ - 1);
    y = std::clamp(y, 0, h_ - 1);
    return v_[static_cast<std::size_t>(y) * w_ + x];
  }
  int w_, h_;
  std::vector<double> v_;
};

// One draw of the simulator's detector cascade at mean λ electrons (variance λ(1 + 1/k) + r²).
inline double draw_cascade(std::mt19937_64& rng, double lambda, const CrlbNoise& nz) {
  const double k = nz.excess > 1 ? 1.0 / (nz.excess - 1.0) : 0.0;
  const int n = std::poisson_distribution<int>(std::max(0.0, lambda))(rng);
  double e = n;
  if (k > 0 && n > 0) e = std::gamma_distribution<double>(n * k, 1.0 / k)(rng);
  if (nz.read_noise_e > 0) e += std::normal_distribution<double>(0.0, nz.read_noise_e)(rng);
  return e;
}

// Accumulated squared errors of an oracle over its fits.
struct OracleSums {
  double pos2 = 0, deg2 = 0;
  int n = 0, failed = 0;
  void add(const OracleError& e) {
    if (!e.ok) {
      ++failed;
      return;
    }
    pos2 += e.dpos2, deg2 += e.dphi * e.dphi, ++n;
  }
  double rms_px() const { return n ? std::sqrt(pos2 / n) : NAN; }
  double rms_deg() const { return n ? std::sqrt(deg2 / n) : NAN; }
};

struct OracleResult {
  // pattern_bias: the pattern fit on the noise-free frame (its bias). support: the pattern fit
  // over the target's own footprint only (coverage >= 0.98 at the truth, inside sempose's
  // circle): a pattern tracker with a perfect learned support — no background pixel at all.
  OracleSums exact, pattern, pattern_bias, support, support_bias;
};

// Both oracles on the simulator's target 0 at state s: `draws` noisy frames (and one
// noise-free one for the pattern fit's bias). nu: the bound's nuisances (scale is fitted by
// the pattern oracle too where it varies); zone_r: sempose's mask radius at scale 1.
inline void oracle_sim(const SimMeanRenderer& sim, const SimState& s, CrlbNuisance nu, const PatternModel& pattern, double zone_r,
                       int draws, std::uint64_t seed, OracleResult& out, bool with_pattern = true) {
  const hal::Roi roi = sim.support_window(s);
  const double D = sim.electrons_per_unit();
  const CrlbNoise nz = sim.noise();
  std::vector<double> b;
  std::vector<float> cover;
  sim.render(roi, s, b, &cover);
  const std::size_t n = b.size();
  std::vector<double> lambda(n), var(n);
  std::vector<std::uint8_t> use_exact(n), use_pattern(n), use_support(n);
  for (std::size_t i = 0; i < n; ++i) {
    lambda[i] = D * std::max(0.0, s.gain * b[i] + s.offset);
    var[i] = std::max(lambda[i] * nz.excess + nz.read_noise_e * nz.read_noise_e, 1e-9);
    use_exact[i] = cover[i] > 1e-3f;
    const double qx = roi.x + static_cast<double>(i % static_cast<std::size_t>(roi.w)), qy = roi.y + static_cast<double>(i / static_cast<std::size_t>(roi.w));
    use_pattern[i] = std::hypot(qx - s.x, qy - s.y) <= zone_r * s.scale;
    use_support[i] = use_pattern[i] && cover[i] >= 0.98f;
  }
  const OraclePose truth{s.x, s.y, s.phi_deg, s.scale, s.jaw_px};
  auto exact_model = [&](const OraclePose& p, std::vector<double>& m) {
    SimState q = s;
    q.x = p.x, q.y = p.y, q.phi_deg = p.phi_deg, q.scale = p.scale, q.jaw_px = p.jaw_px;
    q.gain = 1, q.offset = 0;
    sim.render(roi, q, m);
  };
  auto pattern_model = [&](const OraclePose& p, std::vector<double>& m) {
    m.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (!use_pattern[i]) {
        m[i] = 0;
        continue;
      }
      m[i] = pattern.at_frame(roi.x + static_cast<double>(i % static_cast<std::size_t>(roi.w)), roi.y + static_cast<double>(i / static_cast<std::size_t>(roi.w)), p);
    }
  };
  std::mt19937_64 rng(seed);
  std::vector<double> y(n);
  std::vector<std::vector<double>> exact_jacobian;
  for (int d = 0; d < draws; ++d) {
    for (std::size_t i = 0; i < n; ++i) y[i] = draw_cascade(rng, lambda[i], nz);
    out.exact.add(fit_ml(exact_model, y, var, use_exact, truth, truth, nu.scale, nu.jaws, 4, &exact_jacobian));
    if (!with_pattern) continue;
    out.pattern.add(fit_ml(pattern_model, y, var, use_pattern, truth, truth, nu.scale, false, 60));
    out.support.add(fit_ml(pattern_model, y, var, use_support, truth, truth, nu.scale, false, 60));
  }
  if (!with_pattern) return;
  out.pattern_bias.add(fit_ml(pattern_model, lambda, var, use_pattern, truth, truth, nu.scale, false, 60));
  out.support_bias.add(fit_ml(pattern_model, lambda, var, use_support, truth, truth, nu.scale, false, 60));
}

// The same on the warped real scene (pure Poisson at dose_e, exact model = the scene itself,
// pattern = the recorded P×P crop's 16-bit levels).
inline void oracle_warp(const WarpScene& scene, double cx, double cy, const PatternModel& pattern, double zone_r, double x, double y,
                        double phi_deg, double dose_e, int draws, std::uint64_t seed, OracleResult& out, bool with_pattern = true) {
  const int P = pattern.size();
  const double half = P / 2.0, reach = half * std::sqrt(2.0) + 2;
  const hal::Roi roi{static_cast<std::int32_t>(std::floor(x - reach)), static_cast<std::int32_t>(std::floor(y - reach)),
                     static_cast<std::int32_t>(2 * reach + 2), static_cast<std::int32_t>(2 * reach + 2)};
  const std::size_t n = static_cast<std::size_t>(roi.w) * roi.h;
  auto exact_model = [&](const OraclePose& p, std::vector<double>& m) {
    m.resize(n);
    const double rad = p.phi_deg * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
    for (std::size_t i = 0; i < n; ++i) {
      const double dx = roi.x + static_cast<double>(i % static_cast<std::size_t>(roi.w)) - p.x,
                   dy = roi.y + static_cast<double>(i / static_cast<std::size_t>(roi.w)) - p.y;
      m[i] = std::max(0.0, scene.sample(cx + dx * cs - dy * sn, cy + dx * sn + dy * cs));
    }
  };
  const OraclePose truth{x, y, phi_deg, 1, 0};
  std::vector<double> b;
  exact_model(truth, b);
  std::vector<double> lambda(n), var(n);
  std::vector<std::uint8_t> use_exact(n), use_pattern(n);
  const double rad = phi_deg * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
  for (std::size_t i = 0; i < n; ++i) {
    lambda[i] = dose_e * b[i];
    var[i] = std::max(lambda[i], 1e-9);
    const double dx = roi.x + static_cast<double>(i % static_cast<std::size_t>(roi.w)) - x,
                 dy = roi.y + static_cast<double>(i / static_cast<std::size_t>(roi.w)) - y;
    const double u = dx * cs - dy * sn, v = dx * sn + dy * cs;
    use_exact[i] = std::fabs(u) <= half && std::fabs(v) <= half;  // crlb_warp's support
    use_pattern[i] = std::hypot(dx, dy) <= zone_r;
  }
  auto pattern_model = [&](const OraclePose& p, std::vector<double>& m) {
    m.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      m[i] = use_pattern[i] ? pattern.at_frame(roi.x + static_cast<double>(i % static_cast<std::size_t>(roi.w)),
                                               roi.y + static_cast<double>(i / static_cast<std::size_t>(roi.w)), p)
                            : 0.0;
  };
  std::mt19937_64 rng(seed);
  std::vector<double> yv(n);
  std::vector<std::vector<double>> exact_jacobian;
  for (int d = 0; d < draws; ++d) {
    for (std::size_t i = 0; i < n; ++i) yv[i] = std::poisson_distribution<int>(std::max(0.0, lambda[i]))(rng);
    out.exact.add(fit_ml(exact_model, yv, var, use_exact, truth, truth, false, false, 4, &exact_jacobian));
    if (!with_pattern) continue;
    const OracleError pe = fit_ml(pattern_model, yv, var, use_pattern, truth, truth, false, false, 60);
    out.pattern.add(pe);
    out.support.add(pe);  // the whole scene moves: every pixel of the pattern is the target's
  }
  if (!with_pattern) return;
  const OracleError pb = fit_ml(pattern_model, lambda, var, use_pattern, truth, truth, false, false, 60);
  out.pattern_bias.add(pb);
  out.support_bias.add(pb);
}

}  // namespace sempose::pose::testing
