#include "sempose/pose/appearance_model.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

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
  return d;
}

}  // namespace sempose::pose
