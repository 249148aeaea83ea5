#include "sempose/pose/scale_probe.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

// The image is read at its own pixels and the pattern is the one interpolated: interpolating
// the noisy image instead smooths its noise by an amount that changes with the stretch (none
// where the grid lands on whole pixels), which biased the reading by +2 % at 2.5 e⁻/px.
// Every stretch is scored over the same image pixels (the support stretched by `window`, the
// smallest factor compared): over each stretch's own support, a larger stretch took in more of
// the target's outer contrast, its window's signal-to-noise was higher, and the ZNCC, which
// noise scales by √(S/(S+N)), favoured it: +0.2 % noise-free to +2.1 % at 2.5 e⁻/px on
// lamella_post (pose_accuracy_bench --scale-bias).
double ScaleProbe::score(const PatternBank& bank, const Measurement& m, double factor, double window, int stride) const noexcept {
  const int p = bank.size_px();
  const int w = scorer_.roi_w(), h = scorer_.roi_h();
  const float* f = scorer_.roi();
  const float* t = bank.pattern(m.j);
  const double c = (p - 1) / 2.0;
  const double cx = m.ux + m.dx + c, cy = m.uy + m.dy + c;  // the pattern centre in the ROI
  const double half = window * c;
  const int x_lo = static_cast<int>(std::ceil(cx - half)), x_hi = static_cast<int>(std::floor(cx + half));
  const int y_lo = static_cast<int>(std::ceil(cy - half)), y_hi = static_cast<int>(std::floor(cy + half));
  if (x_lo < 0 || y_lo < 0 || x_hi > w - 1 || y_hi > h - 1) return -2.0;
  const double inv = 1.0 / factor, inv_window = 1.0 / window;
  // The columns read, worked out once (the same arithmetic as per pixel: the same scores).
  int n_cols = 0;
  for (int x = x_lo; x <= x_hi && n_cols < static_cast<int>(columns_.size()); x += stride) {
    const double pu = c + (x - cx) * inv;
    Column& col = columns_[static_cast<std::size_t>(n_cols++)];
    col.u0 = std::clamp(static_cast<int>(pu), 0, p - 2);
    col.wu = pu - col.u0;
    col.u_near = std::clamp(static_cast<int>(std::lround(c + (x - cx) * inv_window)), 0, p - 1);
  }
  const Column* cols = columns_.data();
  double st = 0, stt = 0, sf = 0, sff = 0, stf = 0, n = 0;
  // Every third row and column of the ROI: a ninth of the cost (the probe's three scores cost
  // less than the walk), the estimate's noise grows by ~3x per frame and the running scale
  // averages it down.
  for (int y = y_lo; y <= y_hi; y += stride) {
    const double pv = c + (y - cy) * inv;
    const int v0 = std::clamp(static_cast<int>(pv), 0, p - 2);
    const double wv = pv - v0;
    const float* fr = f + static_cast<std::ptrdiff_t>(y) * w + x_lo;
    const float* t0 = t + static_cast<std::ptrdiff_t>(v0) * p;
    const float* t1 = t0 + p;
    const int v_near = std::clamp(static_cast<int>(std::lround(c + (y - cy) * inv_window)), 0, p - 1);
    // Only the pattern's support (it is zero outside) stretched by `window`: judged at the
    // nearest pattern pixel of that stretch.
    const float* support = t + static_cast<std::ptrdiff_t>(v_near) * p;
    for (int k = 0; k < n_cols; ++k) {
      const Column& col = cols[k];
      if (support[col.u_near] == 0.0f) continue;
      const int u0 = col.u0;
      const double wu = col.wu;
      const double top = t0[u0] + wu * (t0[u0 + 1] - t0[u0]);
      const double bot = t1[u0] + wu * (t1[u0 + 1] - t1[u0]);
      const double tv = top + wv * (bot - top);
      const double fv = fr[static_cast<std::ptrdiff_t>(k) * stride];
      st += tv;
      stt += tv * tv;
      sf += fv;
      sff += fv * fv;
      stf += tv * fv;
      n += 1;
    }
  }
  if (n < 16) return -2.0;
  const double vt = stt - st * st / n, vf = sff - sf * sf / n;
  if (!(vt > 0) || !(vf > 0)) return -2.0;
  return (stf - st * sf / n) / std::sqrt(vt * vf);
}

void ScaleProbe::score3(const PatternBank& bank, const Measurement& m, const double factor[3], double window, int stride,
                        double out[3]) const noexcept {
  out[0] = out[1] = out[2] = -2.0;
  const int p = bank.size_px();
  const int w = scorer_.roi_w(), h = scorer_.roi_h();
  const float* f = scorer_.roi();
  const float* t = bank.pattern(m.j);
  const double c = (p - 1) / 2.0;
  const double cx = m.ux + m.dx + c, cy = m.uy + m.dy + c;
  const double half = window * c;
  const int x_lo = static_cast<int>(std::ceil(cx - half)), x_hi = static_cast<int>(std::floor(cx + half));
  const int y_lo = static_cast<int>(std::ceil(cy - half)), y_hi = static_cast<int>(std::floor(cy + half));
  if (x_lo < 0 || y_lo < 0 || x_hi > w - 1 || y_hi > h - 1) return;
  const double inv[3] = {1.0 / factor[0], 1.0 / factor[1], 1.0 / factor[2]}, inv_window = 1.0 / window;
  int n_cols = 0;
  for (int x = x_lo; x <= x_hi && n_cols < static_cast<int>(columns3_.size()); x += stride) {
    Column3& col = columns3_[static_cast<std::size_t>(n_cols++)];
    for (int i = 0; i < 3; ++i) {
      const double pu = c + (x - cx) * inv[i];
      col.u0[i] = std::clamp(static_cast<int>(pu), 0, p - 2);
      col.wu[i] = pu - col.u0[i];
    }
    col.u_near = std::clamp(static_cast<int>(std::lround(c + (x - cx) * inv_window)), 0, p - 1);
  }
  const Column3* cols = columns3_.data();
  double st[3] = {}, stt[3] = {}, stf[3] = {}, sf = 0, sff = 0, n = 0;
  for (int y = y_lo; y <= y_hi; y += stride) {
    const float* t0[3];
    const float* t1[3];
    double wv[3];
    for (int i = 0; i < 3; ++i) {
      const double pv = c + (y - cy) * inv[i];
      const int v0 = std::clamp(static_cast<int>(pv), 0, p - 2);
      wv[i] = pv - v0;
      t0[i] = t + static_cast<std::ptrdiff_t>(v0) * p;
      t1[i] = t0[i] + p;
    }
    const float* fr = f + static_cast<std::ptrdiff_t>(y) * w + x_lo;
    const int v_near = std::clamp(static_cast<int>(std::lround(c + (y - cy) * inv_window)), 0, p - 1);
    const float* support = t + static_cast<std::ptrdiff_t>(v_near) * p;
    for (int k = 0; k < n_cols; ++k) {
      const Column3& col = cols[k];
      if (support[col.u_near] == 0.0f) continue;
      const double fv = fr[static_cast<std::ptrdiff_t>(k) * stride];
      for (int i = 0; i < 3; ++i) {
        const int u0 = col.u0[i];
        const double wu = col.wu[i];
        const double top = t0[i][u0] + wu * (t0[i][u0 + 1] - t0[i][u0]);
        const double bot = t1[i][u0] + wu * (t1[i][u0 + 1] - t1[i][u0]);
        const double tv = top + wv[i] * (bot - top);
        st[i] += tv;
        stt[i] += tv * tv;
        stf[i] += tv * fv;
      }
      sf += fv;
      sff += fv * fv;
      n += 1;
    }
  }
  if (n < 16) return;
  const double vf = sff - sf * sf / n;
  for (int i = 0; i < 3; ++i) {
    const double vt = stt[i] - st[i] * st[i] / n;
    if (!(vt > 0) || !(vf > 0)) continue;
    out[i] = (stf[i] - st[i] * sf / n) / std::sqrt(vt * vf);
  }
}

ScaleReading ScaleProbe::read(const PatternBank& bank, const Measurement& m) const noexcept {
  ScaleReading r;
  if (!m.valid) return r;
  // A support cut to the target's shape (a shape mask, a learned support) follows the target's
  // own edges: the common window (the support at 1 − δ) holds the smallest stretch's edge but
  // cuts the larger ones', and the reading ran low (the gripper with learned appearance drifted
  // to 0.89–0.95 and was lost: pose_appearance_closed_loop_test). There each stretch is scored
  // over its own support, as before the common window.
  const bool own_windows = bank.has_shape();
  double s3[3];
  if (own_windows) {
    s3[0] = score(bank, m, 1.0 - kStep, 1.0 - kStep);
    s3[1] = score(bank, m, 1.0, 1.0);
    s3[2] = score(bank, m, 1.0 + kStep, 1.0 + kStep);
  } else {
    const double factors[3] = {1.0 - kStep, 1.0, 1.0 + kStep};
    score3(bank, m, factors, 1.0 - kStep, kStride, s3);
  }
  const double lo = s3[0], mid = s3[1], hi = s3[2];
  if (lo < -1.5 || mid < -1.5 || hi < -1.5) return r;
  const double curv = lo - 2.0 * mid + hi;
  if (!(curv < 0)) {
    // No maximum between the three: step towards the better side by one δ at most.
    r.valid = true;
    r.factor = hi > lo ? 1.0 + kStep : 1.0 - kStep;
    return r;
  }
  const double e = std::clamp(0.5 * (lo - hi) / curv, -1.0, 1.0) * kStep;
  r.valid = true;
  r.factor = 1.0 + e;
  return r;
}

}  // namespace sempose::pose
