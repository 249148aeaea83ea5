#include "sempose/pose/appearance_observer.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/window_noise.hpp"

namespace sempose::pose {

AppearanceStats::AppearanceStats(int n)
    : size_px(n),
      sum_r2(static_cast<std::size_t>(n) * n, 0.0),
      sum_obs(static_cast<std::size_t>(n) * n, 0.0),
      hits(static_cast<std::size_t>(n) * n, 0) {}

void AppearanceStats::clear() noexcept {
  frames = 0;
  sum_noise_var = 0;
  std::fill(sum_r2.begin(), sum_r2.end(), 0.0);
  std::fill(sum_obs.begin(), sum_obs.end(), 0.0);
  std::fill(hits.begin(), hits.end(), 0u);
  sum_fx = sum_fy = sum_fxx = sum_fyy = sum_dphi = sum_dphi2 = phi0_deg = 0;
}

double AppearanceStats::motion_spread_px(double radius_px) const noexcept {
  if (frames <= 1) return 0.0;
  const double k = frames;
  const double vx = std::max(0.0, sum_fxx / k - (sum_fx / k) * (sum_fx / k));
  const double vy = std::max(0.0, sum_fyy / k - (sum_fy / k) * (sum_fy / k));
  const double vphi = std::max(0.0, sum_dphi2 / k - (sum_dphi / k) * (sum_dphi / k));
  return std::sqrt(vx + vy) + std::sqrt(vphi) * (M_PI / 180.0) * radius_px;
}

void AppearanceStats::add(const AppearanceStats& o) noexcept {
  if (o.size_px != size_px) return;
  set = o.set;
  frames += o.frames;
  sum_noise_var += o.sum_noise_var;
  // The motion sums are the batch's own (a running total's spread is not read).
  sum_fx += o.sum_fx;
  sum_fy += o.sum_fy;
  sum_fxx += o.sum_fxx;
  sum_fyy += o.sum_fyy;
  sum_dphi += o.sum_dphi;
  sum_dphi2 += o.sum_dphi2;
  for (std::size_t i = 0; i < sum_r2.size(); ++i) {
    sum_r2[i] += o.sum_r2[i];
    sum_obs[i] += o.sum_obs[i];
    hits[i] += o.hits[i];
  }
}

std::size_t AppearanceStats::memory_bytes() const noexcept {
  return (sum_r2.size() + sum_obs.size()) * sizeof(double) + hits.size() * sizeof(std::uint32_t);
}

AppearanceObserver::AppearanceObserver(int n, const std::uint8_t* inside, int frames_per_batch,
                                       double prefilter_noise_gain, int prefilter_passes)
    : n_(n),
      inside_(inside, inside + static_cast<std::size_t>(n) * n),
      frames_per_batch_(std::max(1, frames_per_batch)),
      noise_gain_(prefilter_noise_gain),
      passes_(prefilter_passes),
      sampled_(static_cast<std::size_t>(n) * n, 0.0f),
      buf_{AppearanceStats(n), AppearanceStats(n)} {}

void AppearanceObserver::add_reference(std::vector<float> prefiltered) { refs_.push_back(std::move(prefiltered)); }

// One row in kRowPhases of the window, the phase advancing per frame (window_noise.hpp).
double AppearanceObserver::window_noise_var(const std::uint16_t* raw, std::ptrdiff_t stride, int x0, int y0, int p,
                                            int phase) const noexcept {
  return pose::window_noise_var(raw, stride, x0, y0, p, 1 + phase, kRowPhases);
}

bool AppearanceObserver::observe(std::uint8_t set, const float* roi, int w, int h, const std::uint16_t* raw,
                                 std::ptrdiff_t raw_stride, int bits, double cx, double cy, double phi_deg,
                                 double field_x, double field_y) noexcept {
  if (set >= refs_.size() || n_ < 3) return false;
  AppearanceStats& acc = buf_[filling_];
  if (acc.frames > 0 && acc.set != set) discard();
  const float* t = refs_[set].data();
  const double c = (n_ - 1) / 2.0;
  const double rad = phi_deg * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
  // This frame's rows: one in kRowPhases, the phase advancing per frame.
  const int phase = phase_;
  // Pass 1: the ROI at every support pixel of those rows in the pattern's frame (the inverse
  // of the bank's rotation: source offset s appears at (sx·cos + sy·sin, −sx·sin + sy·cos)
  // from the centre), bilinear; and the sums of the photometric fit f ≈ a·t + b.
  double st = 0, stt = 0, sf = 0, sff = 0, sft = 0, cnt = 0;
  for (int v = phase; v < n_; v += kRowPhases) {
    const double sy = v - c;
    double px = cx - c * cs + sy * sn, py = cy + c * sn + sy * cs;  // u = 0
    // Per-row partial sums in float (≤ 128 terms), accumulated in double per row.
    float rt = 0, rtt = 0, rf = 0, rff = 0, rft = 0, rn = 0;
    for (int u = 0; u < n_; ++u, px += cs, py -= sn) {
      const std::size_t i = static_cast<std::size_t>(v) * n_ + u;
      if (!inside_[i]) continue;
      if (px < 0 || py < 0 || px >= w - 1 || py >= h - 1) return false;
      const int ix = static_cast<int>(px), iy = static_cast<int>(py);
      const float fx = static_cast<float>(px - ix), fy = static_cast<float>(py - iy);
      const float* r = roi + static_cast<std::ptrdiff_t>(iy) * w + ix;
      const float top = r[0] + fx * (r[1] - r[0]), bottom = r[w] + fx * (r[w + 1] - r[w]);
      const float f = top + fy * (bottom - top);
      sampled_[i] = f;
      const float tv = t[i];
      rt += tv;
      rtt += tv * tv;
      rf += f;
      rff += f * f;
      rft += tv * f;
      rn += 1;
    }
    st += rt;
    stt += rtt;
    sf += rf;
    sff += rff;
    sft += rft;
    cnt += rn;
  }
  if (cnt < 16) return false;
  // The frame's detector noise under the pattern (raw window, axis-aligned, the same rows),
  // through the prefilter (noise gain Σk², DC gain of the integer filter): frame units.
  const int x0 = std::clamp(static_cast<int>(std::lround(cx - c)), 0, std::max(0, w - n_));
  const int y0 = std::clamp(static_cast<int>(std::lround(cy - c)), 0, std::max(0, h - n_));
  const double dc = prefilter_dc_gain(passes_, bits);
  const double noise_f =
      window_noise_var(raw, raw_stride, x0, y0, std::min({n_, w, h}), phase) * noise_gain_ * dc * dc;
  // Gain by moment matching (signal variance of the frame over the pattern's), not by
  // regression: pixels the target does not explain (the very background this learns about)
  // are uncorrelated with the pattern and would shrink a regression's gain towards 0, which
  // makes every pixel's residual large. Offset from the means; the sign from the covariance.
  const double var_t = (stt - st * st / cnt) / cnt, var_f = (sff - sf * sf / cnt) / cnt;
  const double cov = (sft - st * sf / cnt) / cnt;
  if (!(var_t > 0) || !(cov > 0) || !(var_f > noise_f)) return false;  // flat, inverted or pure noise
  const double a = std::sqrt((var_f - noise_f) / var_t), b = (sf - a * st) / cnt;
  const double noise = noise_f / (a * a);
  // Pass 2: residuals and aligned observations in pattern units.
  const double inv_a = 1.0 / a;
  for (int v = phase; v < n_; v += kRowPhases) {
    for (int u = 0; u < n_; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * n_ + u;
      if (!inside_[i]) continue;
      const double f = sampled_[i];
      const double r = (f - a * t[i] - b) * inv_a;
      acc.sum_r2[i] += r * r;
      acc.sum_obs[i] += (f - b) * inv_a;
      acc.hits[i] += 1;
    }
  }
  phase_ = (phase_ + 1) % kRowPhases;
  acc.set = set;
  if (acc.frames == 0) acc.phi0_deg = phi_deg;
  {
    const double fx = std::isfinite(field_x) ? field_x : cx, fy = std::isfinite(field_y) ? field_y : cy;
    const double dphi = std::remainder(phi_deg - acc.phi0_deg, 360.0);
    acc.sum_fx += fx;
    acc.sum_fy += fy;
    acc.sum_fxx += fx * fx;
    acc.sum_fyy += fy * fy;
    acc.sum_dphi += dphi;
    acc.sum_dphi2 += dphi * dphi;
  }
  acc.frames += 1;
  acc.sum_noise_var += noise;
  if (acc.frames >= frames_per_batch_ && handed_.load(std::memory_order_acquire) < 0) {
    handed_.store(filling_, std::memory_order_release);
    filling_ ^= 1;  // the worker zeroed it before handing it back
  }
  return true;
}

void AppearanceObserver::discard() noexcept {
  if (buf_[filling_].frames > 0) buf_[filling_].clear();
}

const AppearanceStats* AppearanceObserver::take() noexcept {
  const int k = handed_.load(std::memory_order_acquire);
  return k < 0 ? nullptr : &buf_[k];
}

void AppearanceObserver::give_back() noexcept {
  const int k = handed_.load(std::memory_order_relaxed);
  if (k < 0) return;
  buf_[k].clear();
  handed_.store(-1, std::memory_order_release);
}

std::size_t AppearanceObserver::memory_bytes() const noexcept {
  std::size_t b = buf_[0].memory_bytes() + buf_[1].memory_bytes() + sampled_.size() * sizeof(float) + inside_.size();
  for (const auto& r : refs_) b += r.size() * sizeof(float);
  return b;
}

}  // namespace sempose::pose
