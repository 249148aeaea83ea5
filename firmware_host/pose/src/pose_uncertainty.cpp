// The sandwich covariance of a tracked pose (pose_uncertainty.hpp says what and why).
#include "sempose/pose/pose_uncertainty.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

namespace {
constexpr int kParams = 6;  // x, y, φ, scale, gain, offset

// In-place inverse of a symmetric positive-definite 6×6 matrix by Gauss–Jordan with partial
// pivoting; false when singular (relative pivot below 1e-12).
bool invert6(double a[kParams][kParams]) noexcept {
  double inv[kParams][kParams] = {};
  for (int i = 0; i < kParams; ++i) inv[i][i] = 1.0;
  double scale = 0;
  for (int i = 0; i < kParams; ++i) scale = std::max(scale, std::fabs(a[i][i]));
  if (!(scale > 0) || !std::isfinite(scale)) return false;
  for (int c = 0; c < kParams; ++c) {
    int p = c;
    for (int r = c + 1; r < kParams; ++r)
      if (std::fabs(a[r][c]) > std::fabs(a[p][c])) p = r;
    if (std::fabs(a[p][c]) < 1e-12 * scale) return false;
    if (p != c) {
      for (int k = 0; k < kParams; ++k) {
        std::swap(a[p][k], a[c][k]);
        std::swap(inv[p][k], inv[c][k]);
      }
    }
    const double d = 1.0 / a[c][c];
    for (int k = 0; k < kParams; ++k) {
      a[c][k] *= d;
      inv[c][k] *= d;
    }
    for (int r = 0; r < kParams; ++r) {
      if (r == c) continue;
      const double f = a[r][c];
      if (f == 0) continue;
      for (int k = 0; k < kParams; ++k) {
        a[r][k] -= f * a[c][k];
        inv[r][k] -= f * inv[c][k];
      }
    }
  }
  for (int i = 0; i < kParams; ++i)
    for (int k = 0; k < kParams; ++k) a[i][k] = inv[i][k];
  return true;
}
}  // namespace

PoseUncertainty::PoseUncertainty(const ExactScorer& scorer, int pattern_px, int tile_px, double calibration,
                                 double floor_px, double floor_deg, double noise_factor, double angle_factor)
    : scorer_(scorer),
      pattern_px_(pattern_px),
      tile_(std::max(1, tile_px)),
      calibration_(calibration),
      floor_px_(floor_px),
      floor_deg_(floor_deg),
      noise_factor_(noise_factor),
      angle_factor_(angle_factor),
      tile_sums_(static_cast<std::size_t>(pattern_px / std::max(1, tile_px) + 1) * kParams, 0.0),
      row_(static_cast<std::size_t>(5) * pattern_px, 0.0f) {}

PoseSigma PoseUncertainty::estimate(const PatternBank& bank, const Measurement& m, double scale_factor) noexcept {
  PoseSigma out;
  const int P = pattern_px_;
  const int w = scorer_.roi_w(), h = scorer_.roi_h();
  if (!m.valid || bank.size_px() != P || m.ux < 0 || m.uy < 0 || m.ux + P > w || m.uy + P > h) return out;
  const int n_angles = bank.angles();
  const int j = ((m.j % n_angles) + n_angles) % n_angles;
  const double step_deg = 360.0 / n_angles;
  const float* T = bank.pattern(j);
  const float* Tp = bank.pattern((j + 1) % n_angles);
  const float* Tm = bank.pattern((j + n_angles - 1) % n_angles);
  const float* roi = scorer_.roi();
  const MaskBand* bands = bank.support_bands(j);
  const int n_bands = bank.support_band_count(j);

  // Pass 1: gain and offset of the fit (the copy is zero-mean and unit norm on its support).
  double sum_f = 0, sum_tf = 0, n = 0;
  for (int b = 0; b < n_bands; ++b) {
    const MaskBand& band = bands[b];
    for (int v = band.y0; v <= band.y1; ++v) {
      const float* f = roi + static_cast<std::size_t>(m.uy + v) * w + m.ux;
      const float* t = T + static_cast<std::size_t>(v) * P;
      float sf = 0, stf = 0;
#pragma omp simd reduction(+ : sf, stf)
      for (int u = band.x0; u <= band.x1; ++u) {
        sf += f[u];
        stf += t[u] * f[u];
      }
      sum_f += sf;
      sum_tf += stf;
      n += band.x1 - band.x0 + 1;
    }
  }
  const double gain = sum_tf;
  if (n < kParams * 4 || !(std::fabs(gain) > 1e-6)) return out;
  const float offset = static_cast<float>(sum_f / n);
  const float g = static_cast<float>(gain);
  const float dx = static_cast<float>(m.dx), dy = static_cast<float>(m.dy);
  const float dphi = static_cast<float>(m.dj * step_deg);
  const float ds = static_cast<float>(scale_factor - 1.0);
  const float c = 0.5f * static_cast<float>(P - 1);
  const float per_deg = static_cast<float>(0.5 / step_deg);

  // Pass 2: the Jacobian (pose columns without the gain, which D = diag(g, g, g, g, 1, 1) adds
  // back at the end), the residual at the walk's pose, H0 = Σ J0 J0ᵀ and the tiles' J0ᵀ r.
  double H[kParams][kParams] = {};
  double M[kParams][kParams] = {};
  double G[kParams] = {};
  double sum_r2 = 0;  // the residual's variance: the white-noise (Fisher) part of the covariance  // Σ_b g_b = J0ᵀ r: H0 times the step from the walk's pose to the least-squares optimum
  float* gx = row_.data();
  float* gy = gx + P;
  float* gp = gy + P;
  float* gs = gp + P;
  float* rr = gs + P;
  const int tiles_x = P / tile_ + 1;
  std::fill(tile_sums_.begin(), tile_sums_.end(), 0.0);
  int tile_row = -1;
  auto flush_tile_row = [&]() noexcept {
    for (int tc = 0; tc < tiles_x; ++tc) {
      double* s = tile_sums_.data() + static_cast<std::size_t>(tc) * kParams;
      for (int a = 0; a < kParams; ++a)
        for (int b = 0; b < kParams; ++b) M[a][b] += s[a] * s[b];
      for (int a = 0; a < kParams; ++a) {
        G[a] += s[a];
        s[a] = 0;
      }
    }
  };
  for (int b = 0; b < n_bands; ++b) {
    const MaskBand& band = bands[b];
    for (int v = band.y0; v <= band.y1; ++v) {
      if (v / tile_ != tile_row) {
        flush_tile_row();
        tile_row = v / tile_;
      }
      const float* f = roi + static_cast<std::size_t>(m.uy + v) * w + m.ux;
      const float* t = T + static_cast<std::size_t>(v) * P;
      const float* up = v > 0 ? t - P : t;
      const float* dn = v + 1 < P ? t + P : t;
      const float* tp = Tp + static_cast<std::size_t>(v) * P;
      const float* tm = Tm + static_cast<std::size_t>(v) * P;
      const float yc = static_cast<float>(v) - c;
      const int x0 = band.x0, x1 = band.x1;
      // Central differences inside the support; one-sided where a neighbour is outside it
      // (zero there: a difference across the rim would be the rim's step, not the texture's).
#pragma omp simd
      for (int u = x0; u <= x1; ++u) {
        const float tl = u > x0 ? t[u - 1] : t[u];
        const float tr = u < x1 ? t[u + 1] : t[u];
        const float wx = (u > x0 && u < x1) ? 0.5f : 1.0f;
        const bool in_up = v > 0 && up[u] != 0.0f;
        const bool in_dn = v + 1 < P && dn[u] != 0.0f;
        const float tu = in_up ? up[u] : t[u];
        const float td = in_dn ? dn[u] : t[u];
        const float wy = (in_up && in_dn) ? 0.5f : 1.0f;
        const float ddx = wx * (tr - tl);
        const float ddy = wy * (td - tu);
        const float xc = static_cast<float>(u) - c;
        const float dp = per_deg * (tp[u] - tm[u]);
        const float dsc = xc * ddx + yc * ddy;
        gx[u] = ddx;
        gy[u] = ddy;
        gp[u] = dp;
        gs[u] = dsc;
        rr[u] = f[u] - offset - g * (t[u] - dx * ddx - dy * ddy - ds * dsc + dphi * dp);
      }
      float h00 = 0, h01 = 0, h02 = 0, h03 = 0, h04 = 0, h05 = 0, h11 = 0, h12 = 0, h13 = 0, h14 = 0, h15 = 0;
      float h22 = 0, h23 = 0, h24 = 0, h25 = 0, h33 = 0, h34 = 0, h35 = 0, h44 = 0, h45 = 0;
#pragma omp simd reduction(+ : h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15, h22, h23, h24, h25, h33, h34, h35, h44, h45)
      for (int u = x0; u <= x1; ++u) {
        const float a0 = gx[u], a1 = gy[u], a2 = gp[u], a3 = gs[u], a4 = t[u];
        h00 += a0 * a0; h01 += a0 * a1; h02 += a0 * a2; h03 += a0 * a3; h04 += a0 * a4; h05 += a0;
        h11 += a1 * a1; h12 += a1 * a2; h13 += a1 * a3; h14 += a1 * a4; h15 += a1;
        h22 += a2 * a2; h23 += a2 * a3; h24 += a2 * a4; h25 += a2;
        h33 += a3 * a3; h34 += a3 * a4; h35 += a3;
        h44 += a4 * a4; h45 += a4;
      }
      const float hs[kParams][kParams] = {{h00, h01, h02, h03, h04, h05}, {h01, h11, h12, h13, h14, h15},
                                          {h02, h12, h22, h23, h24, h25}, {h03, h13, h23, h33, h34, h35},
                                          {h04, h14, h24, h34, h44, h45}, {h05, h15, h25, h35, h45, 0}};
      for (int a = 0; a < kParams; ++a)
        for (int k = 0; k < kParams; ++k) H[a][k] += hs[a][k];
      H[5][5] += x1 - x0 + 1;
      for (int u0 = x0; u0 <= x1;) {
        const int tc = u0 / tile_;
        const int u1 = std::min(x1, (tc + 1) * tile_ - 1);
        float s0 = 0, s1 = 0, s2 = 0, s3 = 0, s4 = 0, s5 = 0, r2 = 0;
        for (int u = u0; u <= u1; ++u) {
          const float r = rr[u];
          r2 += r * r;
          s0 += gx[u] * r;
          s1 += gy[u] * r;
          s2 += gp[u] * r;
          s3 += gs[u] * r;
          s4 += t[u] * r;
          s5 += r;
        }
        double* s = tile_sums_.data() + static_cast<std::size_t>(tc) * kParams;
        s[0] += s0; s[1] += s1; s[2] += s2; s[3] += s3; s[4] += s4; s[5] += s5;
        sum_r2 += r2;
        u0 = u1 + 1;
      }
    }
  }
  flush_tile_row();
  if (!invert6(H)) return out;
  // Cov0 = H0⁻¹ M0 H0⁻¹; the pose's σ is √Cov0 over |gain| (D), times the calibration.
  // Plus the walk's own fit error: the squared step δ = H0⁻¹ G from its pose to the
  // least-squares optimum (in the sandwich's meat it is diluted over the tiles). And the
  // white-noise (Fisher) covariance s²·H0⁻¹ with its own factor (README: Uncertainty).
  const double s2 = sum_r2 / std::max(1.0, n - kParams);
  const double gain2 = gain * gain;
  double var[4];
  for (int k = 0; k < 4; ++k) {
    double s = 0, step = 0;
    for (int a = 0; a < kParams; ++a) {
      step += H[k][a] * G[a];
      for (int b = 0; b < kParams; ++b) s += H[k][a] * M[a][b] * H[b][k];
    }
    var[k] = (calibration_ * calibration_ * (s + step * step) + noise_factor_ * noise_factor_ * s2 * H[k][k]) / gain2;
  }
  for (double v : var)
    if (!(v >= 0) || !std::isfinite(v)) return out;
  // The model-error floor (in quadrature): a bias of the pattern against this target that no
  // single frame's residual shows (it is orthogonal to J at the optimum by construction).
  out.x_px = std::hypot(std::sqrt(var[0]), floor_px_);
  out.y_px = std::hypot(std::sqrt(var[1]), floor_px_);
  out.phi_deg = std::hypot(angle_factor_ * std::sqrt(var[2]), floor_deg_);
  out.scale = std::sqrt(var[3]);
  out.valid = true;
  return out;
}

}  // namespace sempose::pose
