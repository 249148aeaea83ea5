#include "sempose/pose/scale_evidence.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

namespace {

// One placed, stretched pattern: its value at a ROI pixel (bilinear in the pattern) and
// whether the pixel is inside its support (nearest pattern pixel non-zero).
struct Placed {
  const float* t;
  int p;
  double c, cx, cy, inv;
  bool at(int x, int y, double& v) const noexcept {
    const double pu = c + (x - cx) * inv, pv = c + (y - cy) * inv;
    if (pu < 0 || pv < 0 || pu > p - 1 || pv > p - 1) return false;
    const int un = static_cast<int>(std::lround(pu)), vn = static_cast<int>(std::lround(pv));
    if (t[static_cast<std::ptrdiff_t>(vn) * p + un] == 0.0f) return false;
    const int u0 = std::min(static_cast<int>(pu), p - 2), v0 = std::min(static_cast<int>(pv), p - 2);
    const double wu = pu - u0, wv = pv - v0;
    const float* r0 = t + static_cast<std::ptrdiff_t>(v0) * p;
    const float* r1 = r0 + p;
    const double top = r0[u0] + wu * (r0[u0 + 1] - r0[u0]);
    const double bot = r1[u0] + wu * (r1[u0 + 1] - r1[u0]);
    v = top + wv * (bot - top);
    return true;
  }
};

}  // namespace

ScaleEvidence ScaleEvidenceCheck::compare(const PatternBank& bank, const Measurement& away, double away_factor,
                                          const Measurement& expected, double expected_factor) const noexcept {
  ScaleEvidence out;
  if (!away.valid || !expected.valid || !(away_factor > 0) || !(expected_factor > 0)) return out;
  const int p = bank.size_px();
  const double c = (p - 1) / 2.0;
  const Placed a{bank.pattern(away.j), p, c, away.ux + away.dx + c, away.uy + away.dy + c, 1.0 / away_factor};
  const Placed b{bank.pattern(expected.j), p, c, expected.ux + expected.dx + c, expected.uy + expected.dy + c,
                 1.0 / expected_factor};
  // Pixels inside both supports lie inside the smaller one's box.
  const Placed& small = away_factor < expected_factor ? a : b;
  const double half = c / small.inv;
  const int w = scorer_.roi_w(), h = scorer_.roi_h();
  const int x_lo = static_cast<int>(std::ceil(small.cx - half)), x_hi = static_cast<int>(std::floor(small.cx + half));
  const int y_lo = static_cast<int>(std::ceil(small.cy - half)), y_hi = static_cast<int>(std::floor(small.cy + half));
  if (x_lo < 0 || y_lo < 0 || x_hi > w - 1 || y_hi > h - 1) return out;
  const float* f = scorer_.roi();
  double n = 0, sa = 0, sb = 0, sf = 0, saa = 0, sbb = 0, sff = 0, saf = 0, sbf = 0, sab = 0;
  for (int y = y_lo; y <= y_hi; ++y) {
    const float* fr = f + static_cast<std::ptrdiff_t>(y) * w;
    for (int x = x_lo; x <= x_hi; ++x) {
      double va = 0, vb = 0;
      if (!a.at(x, y, va) || !b.at(x, y, vb)) continue;
      const double fv = fr[x];
      n += 1;
      sa += va;
      sb += vb;
      sf += fv;
      saa += va * va;
      sbb += vb * vb;
      sff += fv * fv;
      saf += va * fv;
      sbf += vb * fv;
      sab += va * vb;
    }
  }
  if (n < 64) return out;
  const double vaa = saa - sa * sa / n, vbb = sbb - sb * sb / n, vff = sff - sf * sf / n;
  if (!(vaa > 0) || !(vbb > 0) || !(vff > 0)) return out;
  out.valid = true;
  out.pixels = n;
  out.r_away = (saf - sa * sf / n) / std::sqrt(vaa * vff);
  out.r_expected = (sbf - sb * sf / n) / std::sqrt(vbb * vff);
  out.rho = std::clamp((sab - sa * sb / n) / std::sqrt(vaa * vbb), -1.0, 1.0);
  const double q = std::clamp(1.0 - out.r_away * out.r_away, 0.0, 1.0);
  out.noise = std::sqrt(2.0 * (1.0 - out.rho) * q / n);
  const double gain = out.r_away - out.r_expected;
  out.clear = gain > kSigmas * out.noise && gain >= kRigidShare * out.r_away * (1.0 - out.rho);
  return out;
}

}  // namespace sempose::pose
