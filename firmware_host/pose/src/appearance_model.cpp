#include "sempose/pose/appearance_model.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

namespace {

// Keys' cubic (a = −0.5), the bank's own interpolation (bicubic_rotate.cpp), at (x, y) of an
// n×n image; samples outside clamped to the border.
double keys(double t) {
  t = std::abs(t);
  if (t < 1) return (1.5 * t - 2.5) * t * t + 1;
  if (t < 2) return ((-0.5 * t + 2.5) * t - 4) * t + 2;
  return 0;
}

template <class T>
double bicubic(const T* img, int n, double x, double y) {
  const int ix = static_cast<int>(std::floor(x)), iy = static_cast<int>(std::floor(y));
  const double fx = x - ix, fy = y - iy;
  double wx[4], wy[4];
  for (int k = 0; k < 4; ++k) {
    wx[k] = keys(fx - (k - 1));
    wy[k] = keys(fy - (k - 1));
  }
  double s = 0;
  for (int k = 0; k < 4; ++k) {
    const int yy = std::clamp(iy + k - 1, 0, n - 1);
    double r = 0;
    for (int l = 0; l < 4; ++l) r += wx[l] * img[static_cast<std::size_t>(yy) * n + std::clamp(ix + l - 1, 0, n - 1)];
    s += wy[k] * r;
  }
  return s;
}

// Solves the m×m system A x = b in place (Gaussian elimination, partial pivoting). False if singular.
bool solve(double* a, double* b, int m) {
  for (int c = 0; c < m; ++c) {
    int piv = c;
    for (int r = c + 1; r < m; ++r)
      if (std::abs(a[r * m + c]) > std::abs(a[piv * m + c])) piv = r;
    if (!(std::abs(a[piv * m + c]) > 1e-12)) return false;
    if (piv != c) {
      for (int k = 0; k < m; ++k) std::swap(a[c * m + k], a[piv * m + k]);
      std::swap(b[c], b[piv]);
    }
    for (int r = c + 1; r < m; ++r) {
      const double f = a[r * m + c] / a[c * m + c];
      for (int k = c; k < m; ++k) a[r * m + k] -= f * a[c * m + k];
      b[r] -= f * b[c];
    }
  }
  for (int c = m - 1; c >= 0; --c) {
    double v = b[c];
    for (int k = c + 1; k < m; ++k) v -= a[c * m + k] * b[k];
    b[c] = v / a[c * m + c];
  }
  return true;
}

}  // namespace

AppearanceModel::AppearanceModel(const config::AppearanceConfig& cfg, int n, const std::uint8_t* circle,
                                 std::vector<std::vector<float>> references,
                                 std::vector<std::vector<float>> priors)
    : cfg_(cfg), n_(n), circle_(circle, circle + static_cast<std::size_t>(n) * n), refs_(std::move(references)),
      priors_(std::move(priors)) {
  for (std::uint8_t v : circle_) circle_count_ += v;
  priors_.resize(refs_.size());
  for (const auto& t : refs_) {
    std::vector<float> g2(t.size(), 0.0f);
    for (int y = 1; y + 1 < n_; ++y)
      for (int x = 1; x + 1 < n_; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
        const double gx = 0.5 * (t[i + 1] - t[i - 1]), gy = 0.5 * (t[i + n_] - t[i - n_]);
        g2[i] = static_cast<float>(gx * gx + gy * gy);
      }
    grad2_.push_back(std::move(g2));
    sums_.emplace_back(n_);
  }
  pattern_var_.assign(refs_.size(), 0.0);
  grad_var_.assign(refs_.size(), 0.0);
  tsum_.assign(refs_.size(), std::vector<double>(circle_.size(), 0.0));
  thits_.assign(refs_.size(), std::vector<double>(circle_.size(), 0.0));
  tnoise_.assign(refs_.size(), 0.0);
  tframes_.assign(refs_.size(), 0);
}

void AppearanceModel::set_pattern_noise(std::uint8_t set, double var, double grad_var) {
  if (set >= pattern_var_.size()) return;
  pattern_var_[set] = std::max(0.0, var);
  grad_var_[set] = std::max(0.0, grad_var);
}

bool AppearanceModel::align(const std::vector<double>& obs, const std::vector<double>& weight, std::uint8_t set,
                            double p[3], double& gain, double& offset) const {
  const std::vector<float>& t = refs_[set];
  const double c = (n_ - 1) / 2.0;
  // Gradients of the reference (central differences), sampled at the warp like t itself.
  std::vector<float> gxs(t.size(), 0.0f), gys(t.size(), 0.0f);
  for (int y = 0; y < n_; ++y)
    for (int x = 0; x < n_; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
      const int xm = std::max(0, x - 1), xp = std::min(n_ - 1, x + 1), ym = std::max(0, y - 1), yp = std::min(n_ - 1, y + 1);
      gxs[i] = static_cast<float>((t[static_cast<std::size_t>(y) * n_ + xp] - t[static_cast<std::size_t>(y) * n_ + xm]) /
                                  std::max(1, xp - xm));
      gys[i] = static_cast<float>((t[static_cast<std::size_t>(yp) * n_ + x] - t[static_cast<std::size_t>(ym) * n_ + x]) /
                                  std::max(1, yp - ym));
    }
  p[0] = p[1] = p[2] = 0;
  gain = 1;
  offset = 0;
  constexpr int K = 5;
  for (int it = 0; it < 12; ++it) {
    const double th = p[2] * M_PI / 180.0, cs = std::cos(th), sn = std::sin(th);
    double h[K * K] = {}, g[K] = {}, nz[K * K] = {};  // nz: the reference noise's share of h
    double count = 0;
    const double gv = grad_var_[set] * gain * gain, tv = pattern_var_[set];
    for (int y = 0; y < n_; ++y)
      for (int x = 0; x < n_; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
        if (!(weight[i] > 0)) continue;
        const double u = x - c, v = y - c;
        const double wx = c + cs * u - sn * v + p[0], wy = c + sn * u + cs * v + p[1];
        if (wx < 1 || wy < 1 || wx > n_ - 2 || wy > n_ - 2) continue;
        const double tw = bicubic(t.data(), n_, wx, wy);
        const double gx = bicubic(gxs.data(), n_, wx, wy), gy = bicubic(gys.data(), n_, wx, wy);
        // ∂W/∂φ (per degree): R'(φ)(x − c).
        const double dwx = (-sn * u - cs * v) * M_PI / 180.0, dwy = (cs * u - sn * v) * M_PI / 180.0;
        const double j[K] = {gain * gx, gain * gy, gain * (gx * dwx + gy * dwy), tw, 1.0};
        const double r = obs[i] - gain * tw - offset;
        const double w = weight[i];
        for (int a = 0; a < K; ++a) {
          g[a] += w * j[a] * r;
          for (int b = 0; b < K; ++b) h[a * K + b] += w * j[a] * j[b];
        }
        // E[∂n ∂n] of the reference's noise (isotropic, x and y uncorrelated), E[n²] for the gain.
        nz[0 * K + 0] += w * gv;
        nz[1 * K + 1] += w * gv;
        nz[2 * K + 2] += w * gv * (dwx * dwx + dwy * dwy);
        nz[0 * K + 2] += w * gv * dwx;
        nz[1 * K + 2] += w * gv * dwy;
        nz[3 * K + 3] += w * tv;
        count += 1;
      }
    // H_c = H − N, each diagonal kept at ≥ 20 % (a reference that is mostly noise).
    nz[2 * K + 0] = nz[0 * K + 2];
    nz[2 * K + 1] = nz[1 * K + 2];
    for (int a = 0; a < K; ++a) {
      const double f = h[a * K + a] > 0 ? std::min(1.0, 0.8 * h[a * K + a] / std::max(1e-300, nz[a * K + a])) : 0.0;
      for (int b = 0; b < K; ++b) h[a * K + b] -= (nz[a * K + a] > 0 ? f : 1.0) * nz[a * K + b];
    }
    if (count < 64 || !solve(h, g, K)) return false;
    p[0] += g[0];
    p[1] += g[1];
    p[2] += g[2];
    gain += g[3];
    offset += g[4];
    if (!(gain > 0) || !std::isfinite(p[0] + p[1] + p[2]) || std::abs(p[0]) > 4 || std::abs(p[1]) > 4 ||
        std::abs(p[2]) > 20)
      return false;
    if (std::abs(g[0]) < 1e-4 && std::abs(g[1]) < 1e-4 && std::abs(g[2]) < 1e-4) break;
  }
  return true;
}

void AppearanceModel::refine_template(const AppearanceStats& batch, const std::vector<std::uint8_t>& support,
                                      AppearanceDecision& d) {
  const std::uint8_t set = batch.set;
  const std::vector<float>& t = refs_[set];
  const std::size_t nn = circle_.size();
  const double c = (n_ - 1) / 2.0;
  // The gate: a batch that did not move over the background would write that one patch of
  // background into the rim (RMS radius of the circle: R/√2).
  d.motion_px = batch.motion_spread_px(c / std::sqrt(2.0));
  if (d.motion_px < cfg_.refine_min_motion_px) {
    d.template_why = "the batch moved " + std::to_string(d.motion_px) + " px over the background (< " +
                     std::to_string(cfg_.refine_min_motion_px) + ")";
  } else {
    // The batch's mean aligned observation, aligned to the recorded pattern over the support
    // (Matthews–Ishikawa–Baker: the anchor is the recorded pattern, never the last template).
    std::vector<double> obs(nn, 0.0), weight(nn, 0.0);
    for (std::size_t i = 0; i < nn; ++i)
      if (circle_[i] && batch.hits[i] > 0) {
        obs[i] = batch.sum_obs[i] / batch.hits[i];
        if (support[i]) weight[i] = batch.hits[i];
      }
    double p[3], gain = 1, offset = 0;
    if (!align(obs, weight, set, p, gain, offset)) {
      d.template_why = "the batch's mean observation could not be aligned to the recorded pattern";
    } else {
      d.align_dx = p[0];
      d.align_dy = p[1];
      d.align_dphi_deg = p[2];
      if (std::hypot(p[0], p[1]) > cfg_.max_drift_px || std::abs(p[2]) > cfg_.max_drift_deg) {
        d.template_why = "the batch's mean observation lies (" + std::to_string(p[0]) + ", " + std::to_string(p[1]) +
                         ") px, " + std::to_string(p[2]) + " deg from the recorded pattern (limits " +
                         std::to_string(cfg_.max_drift_px) + " px, " + std::to_string(cfg_.max_drift_deg) + " deg)";
      } else {
        // Corrected: O(W⁻¹(y)), the observation where it exists, gain·t + offset elsewhere (so
        // the interpolation near the circle's edge mixes in the pattern, not zeros), back in the
        // reference's photometry. The hits follow by nearest neighbour.
        std::vector<double> full(nn);
        for (std::size_t i = 0; i < nn; ++i) full[i] = batch.hits[i] > 0 && circle_[i] ? obs[i] : gain * t[i] + offset;
        const double th = p[2] * M_PI / 180.0, cs = std::cos(th), sn = std::sin(th);
        std::vector<double>& ts = tsum_[set];
        std::vector<double>& th_ = thits_[set];
        for (int y = 0; y < n_; ++y)
          for (int x = 0; x < n_; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
            if (!circle_[i]) continue;
            const double u = x - c - p[0], v = y - c - p[1];
            const double sx = c + cs * u + sn * v, sy = c - sn * u + cs * v;  // R(−φ)
            const int nx = static_cast<int>(std::lround(sx)), ny = static_cast<int>(std::lround(sy));
            if (nx < 0 || ny < 0 || nx >= n_ || ny >= n_) continue;
            const std::size_t k = static_cast<std::size_t>(ny) * n_ + nx;
            if (!circle_[k] || batch.hits[k] == 0) continue;
            const double o = (bicubic(full.data(), n_, sx, sy) - offset) / gain;
            ts[i] += batch.hits[k] * o;
            th_[i] += batch.hits[k];
          }
        tnoise_[set] += batch.sum_noise_var / (gain * gain);
        tframes_[set] += batch.frames;
        d.template_updated = true;
      }
    }
  }
  // The refined template from everything that entered so far: per pixel the minimum-variance
  // blend of the recorded pattern (variance v_rec) and the mean corrected observation
  // (v_obs = per-frame noise / hits), the observations' weight capped at refine_max_weight.
  if (tframes_[set] <= 0 || !(pattern_var_[set] > 0)) {
    if (d.template_why.empty()) d.template_why = "the recorded pattern's noise is not known";
    return;
  }
  const double v_rec = pattern_var_[set], v_frame = tnoise_[set] / tframes_[set];
  d.refined.assign(t.begin(), t.end());
  double nf = 0, wsum = 0, cnt = 0;
  for (std::size_t i = 0; i < nn; ++i) {
    const double hits = thits_[set][i];
    double w = 0, v_obs = 0;
    if (circle_[i] && hits > 0) {
      v_obs = v_frame / hits;
      w = std::min(cfg_.refine_max_weight, v_rec / (v_rec + v_obs));
      d.refined[i] = static_cast<float>((1 - w) * t[i] + w * tsum_[set][i] / hits);
    }
    if (support[i]) {
      nf += ((1 - w) * (1 - w) * v_rec + w * w * v_obs) / v_rec;
      wsum += w;
      cnt += 1;
    }
  }
  d.template_noise_factor = cnt > 0 ? nf / cnt : 1.0;
  d.template_weight = cnt > 0 ? wsum / cnt : 0.0;
}

std::vector<std::uint8_t> AppearanceModel::support_of(const AppearanceStats& s, std::uint8_t set) const {
  std::vector<std::uint8_t> out(circle_.size(), 0);
  if (set >= refs_.size() || s.frames <= 0) return out;
  const double noise = s.sum_noise_var / s.frames;
  const double jitter2 = cfg_.pose_jitter_px * cfg_.pose_jitter_px;
  const double angle_jitter = cfg_.angle_jitter_deg * M_PI / 180.0, c = (n_ - 1) / 2.0;
  const std::vector<float>& g2 = grad2_[set];
  const std::vector<float>& prior = priors_[set];
  // Per pixel: the mean squared residual and what noise and jitter explain there.
  std::vector<double> msr(circle_.size(), 0.0), expected(circle_.size(), 0.0);
  for (int y = 0; y < n_; ++y)
    for (int x = 0; x < n_; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
      if (!circle_[i] || s.hits[i] == 0) continue;
      const double r2 = (x - c) * (x - c) + (y - c) * (y - c);
      msr[i] = s.sum_r2[i] / s.hits[i];
      expected[i] = noise + (jitter2 + angle_jitter * angle_jitter * r2) * g2[i];
    }
  auto keep = [&](int x0, int y0, int x1, int y1) {  // the ratio test over a rectangle
    double m = 0, e = 0;
    for (int y = std::max(0, y0); y < std::min(n_, y1); ++y)
      for (int x = std::max(0, x0); x < std::min(n_, x1); ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
        m += msr[i];
        e += expected[i];
      }
    return e > 0 && m <= cfg_.outlier_ratio * e;
  };
  auto allowed = [&](std::size_t i) { return circle_[i] && s.hits[i] > 0 && (prior.empty() || prior[i] != 0.0f); };
  // Blocks first (enough samples to tell 2x the noise from noise in one batch), then the
  // pixels next to kept blocks whose own 3x3 neighbourhood passes: a target's outline lies
  // beside the background that changes, and a block holding both would drop the outline,
  // which carries the position.
  const int bs = std::max(1, cfg_.block_px);
  for (int by = 0; by < n_; by += bs)
    for (int bx = 0; bx < n_; bx += bs) {
      if (!keep(bx, by, bx + bs, by + bs)) continue;
      for (int y = by; y < std::min(n_, by + bs); ++y)
        for (int x = bx; x < std::min(n_, bx + bs); ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
          out[i] = allowed(i);
        }
    }
  if (bs > 1) {
    const std::vector<std::uint8_t> core = out;
    for (int y = 0; y < n_; ++y)
      for (int x = 0; x < n_; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
        if (out[i] || !allowed(i)) continue;
        bool near = false;
        for (int dy = -bs; dy <= bs && !near; ++dy)
          for (int dx = -bs; dx <= bs && !near; ++dx) {
            const int xx = x + dx, yy = y + dy;
            near = xx >= 0 && yy >= 0 && xx < n_ && yy < n_ && core[static_cast<std::size_t>(yy) * n_ + xx];
          }
        if (near && keep(x - 1, y - 1, x + 2, y + 2)) out[i] = 1;
      }
  }
  return out;
}

bool AppearanceModel::consistent(const AppearanceStats& s, const std::vector<std::uint8_t>& support, std::uint8_t set,
                                 AppearanceDecision& d) const {
  const std::vector<float>& t = refs_[set];
  // ZNCC over the support of the mean observation with the recorded pattern shifted by
  // (dx, dy); the support lies ≥ 2 px inside the square (the circle's inset), so shifts of
  // ±2 stay in the pattern.
  constexpr int kR = 2;
  auto zncc = [&](int dx, int dy) {
    double so = 0, st = 0, soo = 0, stt = 0, sot = 0, k = 0;
    for (int y = 0; y < n_; ++y)
      for (int x = 0; x < n_; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * n_ + x;
        if (!support[i]) continue;
        const int xs = x + dx, ys = y + dy;
        if (xs < 0 || ys < 0 || xs >= n_ || ys >= n_) return -1.0;
        const double o = s.sum_obs[i] / s.hits[i], tv = t[static_cast<std::size_t>(ys) * n_ + xs];
        so += o;
        st += tv;
        soo += o * o;
        stt += tv * tv;
        sot += o * tv;
        k += 1;
      }
    if (k < 16) return -1.0;
    const double vo = soo - so * so / k, vt = stt - st * st / k, c = sot - so * st / k;
    return vo > 0 && vt > 0 ? c / std::sqrt(vo * vt) : -1.0;
  };
  double z[2 * kR + 1][2 * kR + 1];
  int bx = 0, by = 0;
  for (int dy = -kR; dy <= kR; ++dy)
    for (int dx = -kR; dx <= kR; ++dx) {
      z[dy + kR][dx + kR] = zncc(dx, dy);
      if (z[dy + kR][dx + kR] > z[by + kR][bx + kR]) {
        bx = dx;
        by = dy;
      }
    }
  auto vertex = [](double l, double m, double r) {
    const double den = l - 2 * m + r;
    return den < 0 ? std::clamp(0.5 * (l - r) / den, -0.5, 0.5) : 0.0;
  };
  double ox = bx, oy = by;
  if (std::abs(bx) < kR) ox += vertex(z[by + kR][bx + kR - 1], z[by + kR][bx + kR], z[by + kR][bx + kR + 1]);
  if (std::abs(by) < kR) oy += vertex(z[by + kR - 1][bx + kR], z[by + kR][bx + kR], z[by + kR + 1][bx + kR]);
  d.consistency = z[by + kR][bx + kR];
  d.drift_px = std::hypot(ox, oy);
  if (d.consistency < cfg_.min_consistency) {
    d.why = "the mean observation matches the recorded pattern with ZNCC " + std::to_string(d.consistency) + " < " +
            std::to_string(cfg_.min_consistency);
    return false;
  }
  if (d.drift_px > cfg_.max_drift_px) {
    d.why = "the mean observation lies " + std::to_string(d.drift_px) + " px from the recorded pattern (> " +
            std::to_string(cfg_.max_drift_px) + ")";
    return false;
  }
  return true;
}

AppearanceDecision AppearanceModel::update(const AppearanceStats& batch) {
  AppearanceDecision d;
  const std::uint8_t set = batch.set;
  if (set >= refs_.size() || batch.size_px != n_ || batch.frames <= 0) {
    d.why = "batch does not fit the model";
    return d;
  }
  AppearanceStats candidate = sums_[set];
  candidate.add(batch);
  d.frames = candidate.frames;
  d.support = support_of(candidate, set);
  std::int64_t kept = 0;
  for (std::uint8_t v : d.support) kept += v;
  d.support_fraction = circle_count_ > 0 ? static_cast<double>(kept) / static_cast<double>(circle_count_) : 0.0;
  if (d.support_fraction < cfg_.min_support_fraction) {
    d.why = "the support would keep " + std::to_string(d.support_fraction) + " of the circle (< " +
            std::to_string(cfg_.min_support_fraction) + ")";
    return d;
  }
  if (!consistent(candidate, d.support, set, d)) return d;
  sums_[set] = std::move(candidate);
  d.accepted = true;
  if (cfg_.refine_template) refine_template(batch, d.support, d);
  return d;
}

}  // namespace sempose::pose
