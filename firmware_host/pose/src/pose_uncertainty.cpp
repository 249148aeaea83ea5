// The sandwich covariance of a tracked pose (pose_uncertainty.hpp says what and why).
#include "sempose/pose/pose_uncertainty.hpp"
#include "sempose/pose/simd_clones.hpp"

#include <algorithm>
#include <cmath>


namespace sempose::pose {

namespace {
constexpr int kParams = 6;  // x, y, φ, scale, gain, offset

// One support row of pass 2: what the row needs, read-only.
struct RowInputs {
  const float *f, *t, *up, *dn, *tp, *tm;  // ROI row, the copy's row and its neighbours, the neighbouring angles' rows
  int x0, x1, P;
  bool has_up, has_dn;
  float yc, c, per_deg, offset, g, dx, dy, ds, dphi;
  float px = 0, py = 0;  // the background plane's slopes per pixel (0: the fit used none)
};

// The row's Jacobian (gradients: central differences inside the support, one-sided where a
// neighbour is outside it — zero there: a difference across the rim would be the rim's step,
// not the texture's), its residual at the walk's pose, the column sums of J0·r and r² (col:
// 7 × P) and H0's 20 distinct sums (h). gx: P floats of scratch. Every load is unconditional
// (up/dn are valid rows) so that the loop vectorises. Not cloned for AVX-512 / AVX2: those
// clones measured slower here (pose_speed_bench, 192²: +65 µs against +30 µs).
template <bool kWithH>
[[gnu::always_inline]] inline void row_terms(const RowInputs& in, float* gx, float* col, float* h) noexcept {
  const float* t = in.t;
  const int x0 = in.x0, x1 = in.x1, P = in.P;
  gx[x0] = x1 > x0 ? t[x0 + 1] - t[x0] : 0.0f;
  gx[x1] = x1 > x0 ? t[x1] - t[x1 - 1] : 0.0f;
#pragma omp simd
  for (int u = x0 + 1; u < x1; ++u) gx[u] = 0.5f * (t[u + 1] - t[u - 1]);
  float h00 = 0, h01 = 0, h02 = 0, h03 = 0, h04 = 0, h05 = 0, h11 = 0, h12 = 0, h13 = 0, h14 = 0, h15 = 0;
  float h22 = 0, h23 = 0, h24 = 0, h25 = 0, h33 = 0, h34 = 0, h35 = 0, h44 = 0, h45 = 0;
#pragma omp simd reduction(+ : h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15, h22, h23, h24, h25, h33, h34, h35, h44, h45)
  for (int u = x0; u <= x1; ++u) {
    const float tu0 = in.up[u], td0 = in.dn[u], tc = t[u];
    const bool in_up = in.has_up & (tu0 != 0.0f);
    const bool in_dn = in.has_dn & (td0 != 0.0f);
    const float tu = in_up ? tu0 : tc;
    const float td = in_dn ? td0 : tc;
    const float wy = (in_up & in_dn) ? 0.5f : 1.0f;
    const float a0 = gx[u];
    const float a1 = wy * (td - tu);
    const float a2 = in.per_deg * (in.tp[u] - in.tm[u]);
    const float a3 = (static_cast<float>(u) - in.c) * a0 + in.yc * a1;
    const float r = in.f[u] - (in.offset + in.px * (static_cast<float>(u) - in.c) + in.py * in.yc) -
                    in.g * (tc - in.dx * a0 - in.dy * a1 - in.ds * a3 + in.dphi * a2);
    col[u] += a0 * r;
    col[P + u] += a1 * r;
    col[2 * P + u] += a2 * r;
    col[3 * P + u] += a3 * r;
    col[4 * P + u] += tc * r;
    col[5 * P + u] += r;
    col[6 * P + u] += r * r;
    if constexpr (kWithH) {
      h00 += a0 * a0; h01 += a0 * a1; h02 += a0 * a2; h03 += a0 * a3; h04 += a0 * tc; h05 += a0;
      h11 += a1 * a1; h12 += a1 * a2; h13 += a1 * a3; h14 += a1 * tc; h15 += a1;
      h22 += a2 * a2; h23 += a2 * a3; h24 += a2 * tc; h25 += a2;
      h33 += a3 * a3; h34 += a3 * tc; h35 += a3;
      h44 += tc * tc; h45 += tc;
    }
  }
  if constexpr (!kWithH) return;
  const float out[20] = {h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15, h22, h23, h24, h25, h33, h34, h35, h44, h45};
  for (int i = 0; i < 20; ++i) h[i] = out[i];
}

// The rows of an angle whose H0 is cached: element-wise terms only (no reduction, whose order
// would follow the vector width), so cloned for AVX-512 / AVX2 — each element the same value
// as the baseline's (this file is compiled without fused multiply-adds: CMakeLists.txt).
// perf, pose_speed_bench --profile 192: estimate() was the largest cost of a tracked frame.
SEMPOSE_CLONES void row_terms_cached(const RowInputs& in, float* gx, float* col) noexcept {
  row_terms<false>(in, gx, col, nullptr);
}

// The frame's sharpness against the copy (PoseSigma::sharpness): Σ ∂T·∂f and Σ (∂T)² over x and
// y (central differences), at support pixels whose four neighbours are in the support too (a
// difference across the rim would be the rim's step). f: the ROI at the pattern's origin, stride w.
struct SharpnessSums {
  double cross = 0, self = 0;
};
SharpnessSums sharpness_sums(const float* T, const float* f, std::ptrdiff_t w, int P, const MaskBand* bands,
                             int n_bands) noexcept {
  SharpnessSums out;
  for (int b = 0; b < n_bands; ++b) {
    const MaskBand& band = bands[b];
    const int v0 = std::max(1, band.y0), v1 = std::min(P - 2, band.y1);
    const int u0 = std::max(1, band.x0), u1 = std::min(P - 2, band.x1);
    for (int v = v0; v <= v1; ++v) {
      const float* t = T + static_cast<std::size_t>(v) * P;
      const float* fr = f + v * w;
      float cross = 0, self = 0;
#pragma omp simd reduction(+ : cross, self)
      for (int u = u0; u <= u1; ++u) {
        const bool in = (t[u - 1] != 0.0f) & (t[u + 1] != 0.0f) & (t[u - P] != 0.0f) & (t[u + P] != 0.0f);
        const float ax = in ? 0.5f * (t[u + 1] - t[u - 1]) : 0.0f;
        const float ay = in ? 0.5f * (t[u + P] - t[u - P]) : 0.0f;
        const float fx = 0.5f * (fr[u + 1] - fr[u - 1]), fy = 0.5f * (fr[u + w] - fr[u - w]);
        cross += ax * fx + ay * fy;
        self += ax * ax + ay * ay;
      }
      out.cross += cross;
      out.self += self;
    }
  }
  return out;
}

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
                                 double floor_px, double floor_deg, double noise_factor, double angle_factor,
                                 int max_angles, bool pattern_noise, double scale_factor)
    : scorer_(scorer),
      pattern_px_(pattern_px),
      tile_(std::max(1, tile_px)),
      calibration_(calibration),
      floor_px_(floor_px),
      floor_deg_(floor_deg),
      noise_factor_(noise_factor),
      angle_factor_(angle_factor),
      scale_factor_(scale_factor),
      pattern_noise_(pattern_noise),
      tile_sums_(static_cast<std::size_t>(pattern_px / std::max(1, tile_px) + 1) * kParams, 0.0),
      row_(static_cast<std::size_t>(8) * pattern_px, 0.0f),
      h0_cache_(static_cast<std::size_t>(std::max(0, max_angles)) * kParams * kParams, 0.0),
      h0_valid_(static_cast<std::size_t>(std::max(0, max_angles)), 0) {}

namespace {

// Gain, level (the offset at the pattern's centre) and the plane's slopes per pixel of a window
// whose pattern-only fit gave gain = Σtf and level = Σf / n (f: the scorer's mean-free ROI):
// f regressed on the copy and the centred x, y of the bank's plane Gram.
void plane_fit(const ExactScorer& scorer, const PatternBank& bank, int j, const Measurement& m, double n, double& gain,
               double& level, double& slope_x, double& slope_y) noexcept {
  const PlaneParts q = scorer.plane_parts_given_sum(bank, j, m.ux, m.uy, level * n);
  const PatternBank::PlaneGram& pg = bank.plane_gram(j);
  const double b[3] = {gain, q.xf, q.yf};
  double z[3];
  if (!q.inside || !pg.solve(b, z)) return;
  const int P = bank.size_px();
  gain = z[0];
  level -= z[1] * pg.mean_x + z[2] * pg.mean_y;
  slope_x = z[1] / P;
  slope_y = z[2] / P;
}

}  // namespace

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
  double gain = sum_tf, level = sum_f / n, slope_x = 0, slope_y = 0;
  // A pose the walk fitted with the background plane (SubpixelFit) is judged with it: gain,
  // offset and the plane's slopes fitted together (the regressors of PatternBank::PlaneGram).
  // Without it the ramp stays in the residual, whose pull on x and y (δ below) is the very bias
  // the plane took off the pose: σ doubled and tripled on the charging gradient's frames.
  if (m.background_plane && n > 0) plane_fit(scorer_, bank, j, m, n, gain, level, slope_x, slope_y);
  if (n < kParams * 4 || !(std::fabs(gain) > 1e-6)) return out;
  const float offset = static_cast<float>(level);
  const float g = static_cast<float>(gain);
  const float dx = static_cast<float>(m.dx), dy = static_cast<float>(m.dy);
  const float dphi = static_cast<float>(m.dj * step_deg);
  const float ds = static_cast<float>(scale_factor - 1.0);
  const float c = 0.5f * static_cast<float>(P - 1);
  const float per_deg = static_cast<float>(0.5 / step_deg);

  // Pass 2: the Jacobian (pose columns without the gain, which D = diag(g, g, g, g, 1, 1) adds
  // back at the end), the residual at the walk's pose, H0 = Σ J0 J0ᵀ and the tiles' J0ᵀ r.
  double H[kParams][kParams] = {};
  // H0 depends on the bank's copy at angle j only: kept per angle after its first frame. The
  // cache follows the last bank used; that bank is never freed while in use (the learned-bank
  // slots are only replaced when not in use), so its address cannot come back as another bank.
  if (&bank != cached_bank_) {
    std::fill(h0_valid_.begin(), h0_valid_.end(), std::uint8_t{0});
    cached_bank_ = &bank;
  }
  const bool cacheable = j < static_cast<int>(h0_valid_.size());
  const bool cached_h = cacheable && h0_valid_[static_cast<std::size_t>(j)] != 0;
  if (cached_h) {
    const double* c0 = h0_cache_.data() + static_cast<std::size_t>(j) * kParams * kParams;
    for (int a = 0; a < kParams; ++a)
      for (int k = 0; k < kParams; ++k) H[a][k] = c0[a * kParams + k];
  }
  double M[kParams][kParams] = {};
  double G[kParams] = {};  // Σ_b g_b = J0ᵀ r: H0 times the step from the walk's pose to the least-squares optimum
  double sum_r2 = 0;       // the residual's variance: the white-noise (Fisher) part of the covariance
  float* gx = row_.data();  // scratch: one row's ∂T/∂x
  // Per pattern column, the current tile row's sums of J0·r (6) and r² (vectorised over the
  // row; folded into the tiles when the tile row ends).
  float* col = gx + P;  // 7 × P
  std::fill(col, col + 7 * P, 0.0f);
  const int tiles_x = P / tile_ + 1;
  std::fill(tile_sums_.begin(), tile_sums_.end(), 0.0);
  int tile_row = -1;
  auto flush_tile_row = [&]() noexcept {
    for (int tc = 0; tc < tiles_x; ++tc) {
      double* s = tile_sums_.data() + static_cast<std::size_t>(tc) * kParams;
      const int u0 = tc * tile_, u1 = std::min(P, u0 + tile_);
      for (int a = 0; a < kParams; ++a) {
        const float* ca = col + a * P;
        float sum = 0;
        for (int u = u0; u < u1; ++u) sum += ca[u];
        s[a] += sum;
      }
      for (int u = u0; u < u1; ++u) sum_r2 += col[6 * P + u];
    }
    std::fill(col, col + 7 * P, 0.0f);
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
      RowInputs in;
      in.f = roi + static_cast<std::size_t>(m.uy + v) * w + m.ux;
      in.t = T + static_cast<std::size_t>(v) * P;
      in.up = v > 0 ? in.t - P : in.t;
      in.dn = v + 1 < P ? in.t + P : in.t;
      in.tp = Tp + static_cast<std::size_t>(v) * P;
      in.tm = Tm + static_cast<std::size_t>(v) * P;
      in.x0 = band.x0;
      in.x1 = band.x1;
      in.P = P;
      in.has_up = v > 0;
      in.has_dn = v + 1 < P;
      in.yc = static_cast<float>(v) - c;
      in.c = c;
      in.per_deg = per_deg;
      in.offset = offset;
      in.px = static_cast<float>(slope_x);
      in.py = static_cast<float>(slope_y);
      in.g = g;
      in.dx = dx;
      in.dy = dy;
      in.ds = ds;
      in.dphi = dphi;
      if (cached_h) {
        row_terms_cached(in, gx, col);
        continue;
      }
      float hsum[20];
      row_terms<true>(in, gx, col, hsum);
      const int idx[kParams][kParams] = {{0, 1, 2, 3, 4, 5}, {1, 6, 7, 8, 9, 10}, {2, 7, 11, 12, 13, 14},
                                         {3, 8, 12, 15, 16, 17}, {4, 9, 13, 16, 18, 19}, {5, 10, 14, 17, 19, -1}};
      for (int a = 0; a < kParams; ++a)
        for (int k = 0; k < kParams; ++k)
          if (idx[a][k] >= 0) H[a][k] += hsum[idx[a][k]];
      H[5][5] += band.x1 - band.x0 + 1;
    }
  }
  flush_tile_row();
  if (cacheable && !cached_h) {
    double* c0 = h0_cache_.data() + static_cast<std::size_t>(j) * kParams * kParams;
    for (int a = 0; a < kParams; ++a)
      for (int k = 0; k < kParams; ++k) c0[a * kParams + k] = H[a][k];
    h0_valid_[static_cast<std::size_t>(j)] = 1;
  }
  // The recorded pattern's noise (README: Uncertainty): JᵀJ = H_c + N holds the noise's own
  // gradient energy N, the fit's curvature is H_c only, so the white-noise part is
  // s²·H_c⁻¹ (H_c + N) H_c⁻¹ (the frame's noise against the pattern's noise gradients, the
  // noise × noise term, included), H_c = H0 − λN with λ ≤ 1 keeping every diagonal of H_c at
  // ≥ (1 − kMaxNoiseShare) of H0's. The sandwich keeps H0: its tiles already see the pattern's
  // noise in the residual and its gradients in J (pose_uncertainty_test: with a noisy
  // pattern it is not too small, and with H_c it is 1.3–1.9× too large).
  double H0[kParams][kParams], Hc[kParams][kParams];
  for (int a = 0; a < kParams; ++a)
    for (int k = 0; k < kParams; ++k) H0[a][k] = Hc[a][k] = H[a][k];
  const double* N = pattern_noise_ ? bank.noise_gram(j) : nullptr;
  if (!invert6(H)) return out;  // H0⁻¹
  if (N) {
    double lambda = 1.0;
    for (int k = 0; k < kParams; ++k) {
      const double nk = N[k * kParams + k];
      if (nk > kMaxNoiseShare * H0[k][k]) lambda = std::min(lambda, kMaxNoiseShare * H0[k][k] / nk);
    }
    for (int a = 0; a < kParams; ++a)
      for (int k = 0; k < kParams; ++k) Hc[a][k] -= lambda * N[a * kParams + k];
    if (!invert6(Hc)) return out;  // H_c⁻¹
  }
  // Cov0 = H0⁻¹ M0 H0⁻¹; the pose's σ is √Cov0 over |gain| (D), times the calibration.
  // Plus the walk's own fit error: the squared step δ = H0⁻¹ G from its pose to the
  // least-squares optimum (in the sandwich's meat it is diluted over the tiles). And the
  // white-noise (Fisher) covariance s²·H_c⁻¹ H0 H_c⁻¹ (s²·H0⁻¹ without the pattern's noise)
  // with its own factor (README: Uncertainty).
  const double s2 = sum_r2 / std::max(1.0, n - kParams);
  const double gain2 = gain * gain;
  double var[4];
  for (int k = 0; k < 4; ++k) {
    double s = 0, step = 0, fisher = 0;
    for (int a = 0; a < kParams; ++a) {
      step += H[k][a] * G[a];
      for (int b = 0; b < kParams; ++b) s += H[k][a] * M[a][b] * H[b][k];
    }
    if (N) {
      for (int a = 0; a < kParams; ++a)
        for (int b = 0; b < kParams; ++b) fisher += Hc[k][a] * H0[a][b] * Hc[b][k];
    } else {
      fisher = H[k][k];
    }
    var[k] = (calibration_ * calibration_ * (s + step * step) + noise_factor_ * noise_factor_ * s2 * fisher) / gain2;
  }
  for (double v : var)
    if (!(v >= 0) || !std::isfinite(v)) return out;
  // The model-error floor (in quadrature): a bias of the pattern against this target that no
  // single frame's residual shows (it is orthogonal to J at the optimum by construction).
  out.x_px = std::hypot(std::sqrt(var[0]), floor_px_);
  out.y_px = std::hypot(std::sqrt(var[1]), floor_px_);
  out.phi_deg = std::hypot(angle_factor_ * std::sqrt(var[2]), floor_deg_);
  out.scale = scale_factor_ * std::sqrt(var[3]);
  // The cross term's noise is Σ ∂T·∂n: variance ≈ s²/2 · Σ (∂T)² for white noise (a central
  // difference of white noise has half its variance).
  const SharpnessSums sh = sharpness_sums(T, roi + static_cast<std::size_t>(m.uy) * w + m.ux, w, P, bands, n_bands);
  if (sh.self > 0) {
    out.sharpness = sh.cross / (gain * sh.self);
    out.sharpness_sd = std::sqrt(0.5 * s2 * sh.self) / (std::fabs(gain) * sh.self);
  }
  out.valid = true;
  return out;
}

}  // namespace sempose::pose
