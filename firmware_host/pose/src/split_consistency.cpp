#include "sempose/pose/split_consistency.hpp"

#include <algorithm>
#include <climits>
#include <cmath>

#include <Eigen/Dense>

namespace sempose::pose {

namespace {
// Σ over one part of the regressors r = (t, ∂t/∂x, ∂t/∂y), the window f and their products.
struct Sums {
  double n = 0, r[3] = {}, f = 0, rr[6] = {}, rf[3] = {}, ff = 0;  // rr: 00 01 02 11 12 22
  double ny = 0;  // Σ row index over the part's pixels: its centroid row (when it was scanned)
  double nx = 0;  // Σ column index: its centroid column (a tile's place in the window)
  void add(const Sums& o) noexcept {
    n += o.n, f += o.f, ff += o.ff, ny += o.ny, nx += o.nx;
    for (int i = 0; i < 3; ++i) r[i] += o.r[i], rf[i] += o.rf[i];
    for (int i = 0; i < 6; ++i) rr[i] += o.rr[i];
  }
};

// One part's fit f ≈ b + a·t − a·δ·∇t (a rigid pattern shifted by δ, linearised): the
// displacement δ and its covariance from the residual variance per pixel (× the noise's
// correlation inflation).
struct PartFit {
  bool ok = false;
  double dx = 0, dy = 0, cxx = 0, cxy = 0, cyy = 0;
};

PartFit fit(const Sums& s, double inflation) noexcept {
  PartFit p;
  if (s.n < 32) return p;
  // Centred normal equations C β = d.
  double c[3][3];
  const int idx[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) c[i][k] = s.rr[idx[i][k]] - s.r[i] * s.r[k] / s.n;
  double d[3];
  for (int i = 0; i < 3; ++i) d[i] = s.rf[i] - s.r[i] * s.f / s.n;
  const double ff = s.ff - s.f * s.f / s.n;
  // Inverse of the symmetric 3×3 C.
  const double m00 = c[1][1] * c[2][2] - c[1][2] * c[2][1], m01 = c[0][2] * c[2][1] - c[0][1] * c[2][2],
               m02 = c[0][1] * c[1][2] - c[0][2] * c[1][1];
  const double det = c[0][0] * m00 + c[1][0] * m01 + c[2][0] * m02;
  if (!(std::fabs(det) > 0) || !(ff > 0)) return p;
  double inv[3][3];
  inv[0][0] = m00 / det, inv[0][1] = m01 / det, inv[0][2] = m02 / det;
  inv[1][1] = (c[0][0] * c[2][2] - c[0][2] * c[2][0]) / det;
  inv[1][2] = (c[0][2] * c[1][0] - c[0][0] * c[1][2]) / det;
  inv[2][2] = (c[0][0] * c[1][1] - c[0][1] * c[1][0]) / det;
  inv[1][0] = inv[0][1], inv[2][0] = inv[0][2], inv[2][1] = inv[1][2];
  double b[3];
  for (int i = 0; i < 3; ++i) b[i] = inv[i][0] * d[0] + inv[i][1] * d[1] + inv[i][2] * d[2];
  if (!(b[0] > 0)) return p;
  const double resid = std::max(0.0, ff - (b[0] * d[0] + b[1] * d[1] + b[2] * d[2])) / (s.n - 4) * inflation;
  p.ok = true;
  p.dx = -b[1] / b[0];
  p.dy = -b[2] / b[0];
  // δ = −(β1, β2)/β0: its covariance by the delta method, J Cov(β) Jᵀ with Cov(β) = resid·C⁻¹.
  const double jx[3] = {b[1] / (b[0] * b[0]), -1.0 / b[0], 0.0}, jy[3] = {b[2] / (b[0] * b[0]), 0.0, -1.0 / b[0]};
  double vx = 0, vxy = 0, vy = 0;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      vx += jx[i] * inv[i][k] * jx[k];
      vxy += jx[i] * inv[i][k] * jy[k];
      vy += jy[i] * inv[i][k] * jy[k];
    }
  p.cxx = resid * vx, p.cxy = resid * vxy, p.cyy = resid * vy;
  return p;
}

// The tiles' displacements against one affine field δ(c) = t + A·c about the window's centre c0
// (t a shift; A a turn, a change of size and the shear a target moving while it is scanned
// leaves), weighted by each tile's inverse covariance: χ² of what is left (2 per tile − 6 dof)
// and the largest off-field tile distance among the tiles significantly off it (their own
// 2-dof χ² above kTileOffChi2). (A similarity field, 4 dof, took the scan's shear of the
// `--quick` fast rows for a disagreement: 15 frames UNCERTAIN.)
constexpr double kTileOffChi2 = 9.21;  // χ² (2 dof) at 1 %

template <int N>
void judge_tiles_impl(const Sums (&tile)[N], double c0, double inflation, SplitConsistency& r) noexcept {
  PartFit fits[N];
  Eigen::Matrix2d weight[N];
  double cx[N], cy[N];
  int used = 0;
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
  for (int i = 0; i < N; ++i) {
    fits[i] = fit(tile[i], inflation);
    if (!fits[i].ok) continue;
    const double det = fits[i].cxx * fits[i].cyy - fits[i].cxy * fits[i].cxy;
    if (!(det > 0)) {
      fits[i].ok = false;
      continue;
    }
    weight[i] << fits[i].cyy / det, -fits[i].cxy / det, -fits[i].cxy / det, fits[i].cxx / det;
    cx[i] = tile[i].nx / tile[i].n - c0;
    cy[i] = tile[i].ny / tile[i].n - c0;
    Eigen::Matrix<double, 2, 6> a;
    a << 1, 0, cx[i], cy[i], 0, 0, 0, 1, 0, 0, cx[i], cy[i];
    normal += a.transpose() * weight[i] * a;
    rhs += a.transpose() * weight[i] * Eigen::Vector2d(fits[i].dx, fits[i].dy);
    ++used;
  }
  if (used < 4) return;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(normal);
  if (ldlt.info() != Eigen::Success) return;
  const Eigen::Matrix<double, 6, 1> theta = ldlt.solve(rhs);
  double chi2 = 0, apart = 0;
  for (int i = 0; i < N; ++i) {
    if (!fits[i].ok) continue;
    Eigen::Matrix<double, 2, 6> a;
    a << 1, 0, cx[i], cy[i], 0, 0, 0, 1, 0, 0, cx[i], cy[i];
    const Eigen::Vector2d off = Eigen::Vector2d(fits[i].dx, fits[i].dy) - a * theta;
    const double d2 = off.dot(weight[i] * off);
    if (!std::isfinite(d2)) return;
    chi2 += d2;
    if (d2 > kTileOffChi2) apart = std::max(apart, off.norm());
  }
  r.tiles_valid = true;
  r.tiles_chi2 = chi2;
  r.tiles_dof = 2 * used - 6;
  r.tiles_apart_px = apart;
}
}  // namespace

SplitConsistency SplitConsistencyCheck::measure(const PatternBank& bank, int j, int ux, int uy) const noexcept {
  SplitConsistency r;
  const int p = bank.size_px(), w = scorer_.roi_w(), h = scorer_.roi_h();
  if (ux < 0 || uy < 0 || ux > w - p || uy > h - p || p < 8) return r;
  const MaskBand* bands = bank.support_bands(j);
  const int n_bands = bank.support_band_count(j);
  int y_min = INT_MAX, y_max = INT_MIN;
  for (int k = 0; k < n_bands; ++k) {
    y_min = std::min(y_min, std::max(1, bands[k].y0));
    y_max = std::max(y_max, std::min(p - 2, bands[k].y1));
  }
  if (y_max - y_min + 1 < kParts) return r;
  const int rows = y_max - y_min + 1;
  Sums part[kParts];
  Sums tile[kTiles * kTiles];
  const float* t = bank.pattern(j);
  const float* f = scorer_.roi() + static_cast<std::ptrdiff_t>(uy) * w + ux;
  // Tile columns split [1, p − 2] in kTiles; each row's run is summed per tile column.
  int col_start[kTiles + 1];
  for (int c = 0; c <= kTiles; ++c) col_start[c] = 1 + c * (p - 2) / kTiles;
  for (int k = 0; k < n_bands; ++k) {
    const MaskBand& b = bands[k];
    const int bx0 = std::max(1, b.x0), bx1 = std::min(p - 2, b.x1);
    if (bx1 < bx0) continue;
    for (int y = std::max(1, b.y0); y <= std::min(p - 2, b.y1); ++y) {
      const float* tr = t + static_cast<std::ptrdiff_t>(y) * p;
      const float* tu = tr - p;
      const float* td = tr + p;
      const float* fr = f + static_cast<std::ptrdiff_t>(y) * w;
      Sums& s = part[(y - y_min) * kParts / rows];
      Sums* tile_row = tile + (y - y_min) * kTiles / rows * kTiles;
      for (int c = 0; c < kTiles; ++c) {
        const int x0 = std::max(bx0, col_start[c]), x1 = std::min(bx1, col_start[c + 1] - 1);
        if (x1 < x0) continue;
        float r0 = 0, r1 = 0, r2 = 0, sf = 0, q00 = 0, q01 = 0, q02 = 0, q11 = 0, q12 = 0, q22 = 0, g0 = 0, g1 = 0, g2 = 0,
              sff = 0;
#pragma omp simd reduction(+ : r0, r1, r2, sf, q00, q01, q02, q11, q12, q22, g0, g1, g2, sff)
        for (int x = x0; x <= x1; ++x) {
          const float a = tr[x], gx = 0.5f * (tr[x + 1] - tr[x - 1]), gy = 0.5f * (td[x] - tu[x]), v = fr[x];
          r0 += a, r1 += gx, r2 += gy, sf += v;
          q00 += a * a, q01 += a * gx, q02 += a * gy, q11 += gx * gx, q12 += gx * gy, q22 += gy * gy;
          g0 += a * v, g1 += gx * v, g2 += gy * v, sff += v * v;
        }
        Sums run;
        run.n = x1 - x0 + 1;
        run.ny = static_cast<double>(y) * run.n;
        run.nx = 0.5 * (x0 + x1) * run.n;
        run.r[0] = r0, run.r[1] = r1, run.r[2] = r2, run.f = sf;
        run.rr[0] = q00, run.rr[1] = q01, run.rr[2] = q02, run.rr[3] = q11, run.rr[4] = q12, run.rr[5] = q22;
        run.rf[0] = g0, run.rf[1] = g1, run.rf[2] = g2, run.ff = sff;
        s.add(run);
        tile_row[c].add(run);
      }
    }
  }
  judge_tiles_impl(tile, 0.5 * (p - 1), inflation_, r);
  for (int c = 1; c <= kCuts; ++c) {
    Sums first, last;
    for (int k = 0; k < c; ++k) first.add(part[k]);
    for (int k = c; k < kParts; ++k) last.add(part[k]);
    const PartFit a = fit(first, inflation_), b = fit(last, inflation_);
    if (!a.ok || !b.ok) continue;  // a part that does not fit (flat, or no positive gain) says nothing
    const double ddx = a.dx - b.dx, ddy = a.dy - b.dy;
    const double sxx = a.cxx + b.cxx, sxy = a.cxy + b.cxy, syy = a.cyy + b.cyy;
    const double det = sxx * syy - sxy * sxy;
    if (!(det > 0)) continue;
    const double d2 = (syy * ddx * ddx - 2 * sxy * ddx * ddy + sxx * ddy * ddy) / det;
    const double z = std::sqrt(std::max(0.0, d2));
    // Along the scan lines alone: the cut whose parts' x displacements differ by the most SDs.
    if (sxx > 0 && std::fabs(ddx) / std::sqrt(sxx) > r.line_z) {
      r.line_z = std::fabs(ddx) / std::sqrt(sxx);
      r.line_apart_px = std::fabs(ddx);
      r.line_rows_apart = last.ny / last.n - first.ny / first.n;
    }
    if (!r.valid || z > r.z) {
      r.valid = true;
      r.z = z;
      r.apart_px = std::hypot(ddx, ddy);
      r.rows_apart = last.ny / last.n - first.ny / first.n;
      r.cut = c;
    }
  }
  return r;
}

}  // namespace sempose::pose
