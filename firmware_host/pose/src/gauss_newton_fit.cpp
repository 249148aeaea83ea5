// Inverse-compositional Gauss–Newton fit of a pattern template (gauss_newton_fit.hpp).
#include "sempose/pose/gauss_newton_fit.hpp"

#include <algorithm>
#include <cmath>
#include <type_traits>

#include "sempose/pose/window_noise.hpp"

#include "sempose/pose/simd_clones.hpp"

namespace sempose::pose {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;
constexpr int kP = kFitParams;
constexpr int kMinPixels = 64;  // a pattern's support is thousands

// Σ f·w·J (J = sd0..sd3, T, 1) and Σ w·f² at the warp (a00 a01; a10 a11) + (cx, cy), f bilinear
// from the ROI; t, s0..s3 are already multiplied by w. The hot loop, cloned for AVX-512 / AVX2
// (the build targets baseline x86-64).
template <class Px>
SEMPOSE_CLONES void warp_sums(const float* u, const float* v, const float* wt, const float* t, const float* s0,
                              const float* s1, const float* s2, const float* s3, int n, const Px* img,
                              std::ptrdiff_t stride, float a00,
                              float a01, float a10, float a11, float cx, float cy, double* out) noexcept {
  float g0 = 0, g1 = 0, g2 = 0, g3 = 0, g4 = 0, g5 = 0, ff = 0, ph = 0;
#pragma omp simd reduction(+ : g0, g1, g2, g3, g4, g5, ff, ph)
  for (int i = 0; i < n; ++i) {
    const float x = cx + a00 * u[i] + a01 * v[i];
    const float y = cy + a10 * u[i] + a11 * v[i];
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);  // x, y ≥ 0: truncation is floor
    const float fx = x - static_cast<float>(x0), fy = y - static_cast<float>(y0);
    const std::ptrdiff_t k = y0 * stride + x0;
    const float p00 = static_cast<float>(img[k]), p01 = static_cast<float>(img[k + 1]);
    const float p10 = static_cast<float>(img[k + stride]), p11 = static_cast<float>(img[k + stride + 1]);
    const float top = p00 + fx * (p01 - p00), bot = p10 + fx * (p11 - p10);
    const float f = top + fy * (bot - top);
    g0 += f * s0[i];
    g1 += f * s1[i];
    g2 += f * s2[i];
    g3 += f * s3[i];
    g4 += f * t[i];
    const float wf = f * wt[i];
    g5 += wf;
    ff += wf * f;
    // The share of a pixel's noise variance bilinear interpolation keeps at this phase.
    ph += (1.0f - 2.0f * fx * (1.0f - fx)) * (1.0f - 2.0f * fy * (1.0f - fy));
  }
  out[0] = g0;
  out[1] = g1;
  out[2] = g2;
  out[3] = g3;
  out[4] = g4;
  out[5] = g5;
  out[6] = ff;
  out[7] = ph;
}

// Cholesky solve of a symmetric positive definite kP×kP system. False when it is not.
bool solve_spd(const double (&h)[kP][kP], const double (&g)[kP], double (&x)[kP]) noexcept {
  double l[kP][kP] = {};
  for (int i = 0; i < kP; ++i) {
    for (int j = 0; j <= i; ++j) {
      double s = h[i][j];
      for (int k = 0; k < j; ++k) s -= l[i][k] * l[j][k];
      if (i == j) {
        if (!(s > 1e-12 * std::max(1.0, std::fabs(h[i][i])))) return false;
        l[i][i] = std::sqrt(s);
      } else {
        l[i][j] = s / l[j][j];
      }
    }
  }
  double y[kP];
  for (int i = 0; i < kP; ++i) {
    double s = g[i];
    for (int k = 0; k < i; ++k) s -= l[i][k] * y[k];
    y[i] = s / l[i][i];
  }
  for (int i = kP - 1; i >= 0; --i) {
    double s = y[i];
    for (int k = i + 1; k < kP; ++k) s -= l[k][i] * x[k];
    x[i] = s / l[i][i];
  }
  return true;
}

}  // namespace

bool FitTemplate::build(const float* T, int P, const std::uint8_t* inside, const float* variance) {
  const double c = (P - 1) / 2.0;
  for (auto* vec : {&u_, &v_, &w_, &t_, &sd0_, &sd1_, &sd2_, &sd3_}) vec->clear();
  double r2 = 0;
  for (int y = 1; y < P - 1; ++y) {
    for (int x = 1; x < P - 1; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * P + x;
      if (!(inside[i] && inside[i - 1] && inside[i + 1] && inside[i - P] && inside[i + P])) continue;
      const float gx = 0.5f * (T[i + 1] - T[i - 1]), gy = 0.5f * (T[i + P] - T[i - P]);
      const float u = static_cast<float>(x - c), v = static_cast<float>(y - c);
      u_.push_back(u);
      v_.push_back(v);
      w_.push_back(variance != nullptr ? 1.0f / std::max(variance[i], 1e-20f) : 1.0f);
      t_.push_back(T[i]);
      // ∇T · ∂W/∂(tx, ty, θ, ln s) at the identity, W(d) = t + s·R(θ)·d (bicubic_rotate's map:
      // the pattern turned by θ shows at d what the pattern shows at R(θ)·d): ∂W/∂θ = (v, −u),
      // ∂W/∂ln s = (u, v).
      sd0_.push_back(gx);
      sd1_.push_back(gy);
      sd2_.push_back(gx * v - gy * u);
      sd3_.push_back(gx * u + gy * v);
      r2 = std::max(r2, static_cast<double>(u) * u + static_cast<double>(v) * v);
    }
  }
  n_ = static_cast<int>(t_.size());
  radius_ = std::sqrt(r2);
  if (n_ < kMinPixels) return false;
  noise_factor_ = 1.0;
  if (variance != nullptr) {  // weights of mean 1: the Hessian keeps the unweighted one's scale
    double sw = 0, sv = 0;
    for (const float w : w_) {
      sw += w;
      sv += 1.0 / w;
    }
    const float k = static_cast<float>(n_ / sw);
    for (float& w : w_) w *= k;
    // w_i·σ_i² is then the same for every pixel: σ̄²·n² / (Σ v · Σ 1/v), σ̄² the mean variance.
    noise_factor_ = static_cast<double>(n_) * n_ / (sv * sw);
  }
  const std::vector<float>* col[kP - 1] = {&sd0_, &sd1_, &sd2_, &sd3_, &t_};
  for (int r = 0; r < kP; ++r)
    for (int cc = r; cc < kP; ++cc) {
      double s = 0;
      for (int i = 0; i < n_; ++i)
        s += static_cast<double>(w_[i]) * (r < kP - 1 ? (*col[r])[i] : 1.0f) * (cc < kP - 1 ? (*col[cc])[i] : 1.0f);
      m_[r][cc] = m_[cc][r] = s;
    }
  // The loop's streams carry the weight: w·T and w·sd (exactly T and sd with w = 1).
  for (auto* vec : {&t_, &sd0_, &sd1_, &sd2_, &sd3_})
    for (int i = 0; i < n_; ++i) (*vec)[i] *= w_[i];
  return true;
}

FitResult GaussNewtonFit::fit(const FitTemplate& tpl, const float* roi, int w, int h, std::ptrdiff_t stride,
                              const FitPose& start) const noexcept {
  return run(tpl, roi, w, h, stride, start);
}
FitResult GaussNewtonFit::fit(const FitTemplate& tpl, const std::uint16_t* roi, int w, int h, std::ptrdiff_t stride,
                              const FitPose& start) const noexcept {
  return run(tpl, roi, w, h, stride, start);
}

template <class Px>
FitResult GaussNewtonFit::run(const FitTemplate& tpl, const Px* roi, int w, int h, std::ptrdiff_t stride,
                              const FitPose& start) const noexcept {
  FitResult res;
  res.pose = start;
  res.status = FitStatus::kSkipped;
  if (roi == nullptr || tpl.n_ < kMinPixels) return res;
  const auto& m = tpl.m_;
  double s[kP + 2];
  // The frame's noise in the sum of squares (raw source): Σ w·f² holds Σ w_i σ_i² φ_i, φ_i the
  // share of the pixel noise that bilinear interpolation keeps at its phase (1 on a pixel, 1/4
  // between four): the cost falls toward half-pixel phases by noise alone, so the guard compares
  // costs with it taken out. σ̄² from Immerkær's estimator over the fit's window of the raw ROI.
  double noise_kappa = 0;
  if constexpr (std::is_same_v<Px, std::uint16_t>) {
    const int r = static_cast<int>(std::ceil(tpl.radius_ * start.scale)) + 1;
    const int x0 = std::max(0, static_cast<int>(std::floor(start.cx)) - r), y0 = std::max(0, static_cast<int>(std::floor(start.cy)) - r);
    const int side = std::min({2 * r + 1, w - x0, h - y0});
    if (side >= 8) noise_kappa = window_noise_var(roi, stride, x0, y0, side) * tpl.noise_factor_;
  }
  auto pass = [&](const FitPose& p) {
    const double reach = tpl.radius_ * p.scale + 2.0;
    if (!(p.cx - reach >= 0 && p.cy - reach >= 0 && p.cx + reach <= w - 2 && p.cy + reach <= h - 2)) return false;
    const double th = p.phi_deg / kRadToDeg;
    const float a00 = static_cast<float>(p.scale * std::cos(th)), a01 = static_cast<float>(p.scale * std::sin(th));
    warp_sums(tpl.u_.data(), tpl.v_.data(), tpl.w_.data(), tpl.t_.data(), tpl.sd0_.data(), tpl.sd1_.data(), tpl.sd2_.data(),
              tpl.sd3_.data(), tpl.n_, roi, stride, a00, a01, -a01, a00, static_cast<float>(p.cx),
              static_cast<float>(p.cy), s);
    return true;
  };
  // The photometry that minimises the residual at a pass (exact: the model is linear in it),
  // and that minimum: the cost the steps are judged by.
  auto photometry = [&](double& a, double& b) {
    const double d = m[4][4] * m[5][5] - m[4][5] * m[4][5];
    if (!(d > 0)) return -1.0;
    a = (s[4] * m[5][5] - s[5] * m[4][5]) / d;
    b = (m[4][4] * s[5] - m[4][5] * s[4]) / d;
    return s[6] - a * s[4] - b * s[5];
  };
  auto judged = [&](double cost) { return cost - noise_kappa * s[7]; };
  FitPose p = start, prev = start;
  double a = 0, b = 0, prev_judged = 0;
  for (int it = 0; it < cfg_.max_iterations; ++it) {
    if (!pass(p)) {
      if (it == 0) return res;
      break;  // the last step left the ROI: the pose before it
    }
    res.iterations = it + 1;
    const double cost = photometry(a, b);
    if (!(cost >= 0) || !(a > 0)) {  // flat, or the window anti-correlates: nothing to fit
      if (it == 0) return res;
      break;
    }
    const double judged_cost = judged(cost);
    if (it > 0 && judged_cost > prev_judged) break;  // cost-increase guard: keep the pose before the step
    res.gain = a;
    res.offset = b;
    res.rms_residual = std::sqrt(std::max(0.0, cost) / tpl.n_);
    prev_judged = judged_cost;
    prev = p;
    if (it + 1 == cfg_.max_iterations) break;  // no pass left to verify another step
    // Normal equations, pose columns scaled by the gain; at the optimal photometry the
    // gradient's gain and offset parts vanish.
    double hm[kP][kP], g[kP], dp[kP] = {};
    const double sc[kP] = {a, a, a, a, 1, 1};
    for (int r = 0; r < kP; ++r) {
      g[r] = sc[r] * (s[r] - a * m[r][4] - b * m[r][5]);
      for (int cc = 0; cc < kP; ++cc) hm[r][cc] = sc[r] * sc[cc] * m[r][cc];
    }
    if (!cfg_.fit_scale) {
      for (int k = 0; k < kP; ++k) hm[3][k] = hm[k][3] = 0;
      hm[3][3] = 1;
      g[3] = 0;
    }
    if (!solve_spd(hm, g, dp)) {
      res.status = FitStatus::kDiverged;
      res.pose = start;
      return res;
    }
    // The step's size in px: translation, and the rim's displacement for angle and scale.
    const double step = std::max({std::hypot(dp[0], dp[1]), tpl.radius_ * std::fabs(dp[2]), tpl.radius_ * std::fabs(dp[3])});
    // Inverse composition W ← W ∘ W(Δ)⁻¹: θ' = θ − Δθ, s' = s·e^(−Δln s), c' = c − s'·R(θ')·Δt.
    p.phi_deg -= dp[2] * kRadToDeg;
    p.scale *= std::exp(-dp[3]);
    const double th = p.phi_deg / kRadToDeg, cs = std::cos(th), sn = std::sin(th);
    p.cx -= p.scale * (cs * dp[0] + sn * dp[1]);
    p.cy -= p.scale * (-sn * dp[0] + cs * dp[1]);
    const double moved = std::max({std::hypot(p.cx - start.cx, p.cy - start.cy),
                                   tpl.radius_ * std::fabs(p.phi_deg - start.phi_deg) / kRadToDeg,
                                   tpl.radius_ * std::fabs(std::log(p.scale / start.scale))});
    if (!(step <= cfg_.max_move_px) || !(moved <= cfg_.max_move_px)) {
      res.status = FitStatus::kDiverged;
      res.pose = start;
      return res;
    }
    if (step < 1e-3) break;
  }
  res.status = FitStatus::kRefined;
  res.pose = prev;
  return res;
}

}  // namespace sempose::pose
