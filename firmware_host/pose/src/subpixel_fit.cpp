#include "sempose/pose/subpixel_fit.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace sempose::pose {

double fit3(float l, float c, float r, bool gaussian) noexcept {
  double d = 0;
  if (gaussian && l > 0 && c > 0 && r > 0) {
    const double ll = std::log(l), lc = std::log(c), lr = std::log(r);
    const double den = ll - 2 * lc + lr;
    if (den < -1e-12) d = 0.5 * (ll - lr) / den;
  } else {
    const double den = static_cast<double>(l) - 2.0 * c + r;
    if (den < -1e-12) d = 0.5 * (static_cast<double>(l) - r) / den;
  }
  return std::clamp(d, -0.5, 0.5);
}

void SubpixelFit::terms(double x, double y, double j, double* t) noexcept {
  t[0] = 1;
  t[1] = x;
  t[2] = y;
  t[3] = j;
  t[4] = 0.5 * x * x;
  t[5] = 0.5 * y * y;
  t[6] = 0.5 * j * j;
  t[7] = x * y;
  t[8] = x * j;
  t[9] = y * j;
}

// (AᵀA)⁻¹Aᵀ of the fixed 19-sample design, by Gauss-Jordan elimination.
SubpixelFit::SubpixelFit(bool gaussian, bool noise_correction, bool background_plane) noexcept
    : gaussian_(gaussian), noise_correction_(noise_correction), background_plane_(background_plane) {
  double a[kSamples][kTerms];
  for (int i = 0; i < kSamples; ++i) terms(kOffsets[i][0], kOffsets[i][1], kOffsets[i][2], a[i]);
  double m[kTerms][2 * kTerms] = {};
  for (int r = 0; r < kTerms; ++r) {
    for (int c = 0; c < kTerms; ++c)
      for (int i = 0; i < kSamples; ++i) m[r][c] += a[i][r] * a[i][c];
    m[r][kTerms + r] = 1;
  }
  for (int c = 0; c < kTerms; ++c) {
    int piv = c;
    for (int r = c + 1; r < kTerms; ++r)
      if (std::fabs(m[r][c]) > std::fabs(m[piv][c])) piv = r;
    for (int k = 0; k < 2 * kTerms; ++k) std::swap(m[c][k], m[piv][k]);
    const double pv = m[c][c];
    for (int k = 0; k < 2 * kTerms; ++k) m[c][k] /= pv;
    for (int r = 0; r < kTerms; ++r) {
      if (r == c) continue;
      const double f = m[r][c];
      for (int k = 0; k < 2 * kTerms; ++k) m[r][k] -= f * m[c][k];
    }
  }
  for (int r = 0; r < kTerms; ++r)
    for (int i = 0; i < kSamples; ++i) {
      double v = 0;
      for (int c = 0; c < kTerms; ++c) v += m[r][kTerms + c] * a[i][c];
      pinv_[r][i] = v;
    }
}

bool SubpixelFit::joint_fit(const float* s, bool log_scores, double& dx, double& dy, double& dj,
                            float& peak) const noexcept {
  double v[kSamples];
  for (int i = 0; i < kSamples; ++i) {
    if (s[i] <= -2.0f) return false;
    if (log_scores && s[i] <= 0.0f) return false;
    v[i] = log_scores ? std::log(static_cast<double>(s[i])) : s[i];
  }
  double q[kTerms];
  for (int r = 0; r < kTerms; ++r) {
    double acc = 0;
    for (int i = 0; i < kSamples; ++i) acc += pinv_[r][i] * v[i];
    q[r] = acc;
  }
  // H = [[q4, q7, q8], [q7, q5, q9], [q8, q9, q6]] must be negative definite.
  const double a = q[4], b = q[7], c = q[8], e = q[5], f = q[9], k = q[6];
  const double m2 = a * e - b * b;
  const double det = a * (e * k - f * f) - b * (b * k - f * c) + c * (b * f - e * c);
  if (!(a < 0 && m2 > 0 && det < 0)) return false;
  // u = −H⁻¹g by the adjugate.
  const double i00 = e * k - f * f, i01 = c * f - b * k, i02 = b * f - c * e;
  const double i11 = a * k - c * c, i12 = b * c - a * f, i22 = a * e - b * b;
  const double g0 = q[1], g1 = q[2], g2 = q[3];
  const double ux = -(i00 * g0 + i01 * g1 + i02 * g2) / det;
  const double uy = -(i01 * g0 + i11 * g1 + i12 * g2) / det;
  const double uj = -(i02 * g0 + i12 * g1 + i22 * g2) / det;
  // Up to 1.5 steps out (a tie put the grid point on the far side of the peak): the
  // caller recentres and fits again.
  if (!(std::fabs(ux) <= 1.5 && std::fabs(uy) <= 1.5 && std::fabs(uj) <= 1.5)) return false;
  dx = ux;
  dy = uy;
  dj = uj;
  double t[kTerms];
  terms(ux, uy, uj, t);
  double val = 0;
  for (int r = 0; r < kTerms; ++r) val += q[r] * t[r];
  peak = static_cast<float>(log_scores ? std::exp(val) : val);
  return true;
}

namespace {

// Σ² the pattern and the background plane explain together: bᵀG⁻¹b, b = (Σtf, Σxf, Σyf), G their
// Gram. At least the pattern's alone, (Σtf)²; that when G is not positive definite.
double explained_with_plane(const ScoreParts& p, const PlaneParts& q, const PatternBank::PlaneGram& pg) noexcept {
  const double b[3] = {p.tf, q.xf, q.yf};
  double w[3];
  if (!pg.whiten(b, w)) return p.tf * p.tf;
  return std::max(p.tf * p.tf, w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
}

}  // namespace

bool SubpixelFit::plane_scores(ScoreCache& cache, int ux, int uy, const CachedScore* ev, float* fs) const noexcept {
  const PatternBank& bank = cache.bank();
  const ExactScorer& scorer = cache.scorer();
  const ScoreParts& c = ev[4].parts;
  const PlaneParts centre = scorer.plane_parts(bank, ev[4].j, ux, uy, c);
  if (!centre.inside) return false;
  const double explained = explained_with_plane(c, centre, bank.plane_gram(ev[4].j));
  const double rss = c.var - explained;
  if (!(rss > 0) || (explained - c.tf * c.tf) / rss * c.count <= kPlaneSignificance) return false;
  // The circle's support is the same at every angle: its plane products depend on the place
  // only (the 19 samples sit at 9 places), all nine from three passes. A turned shape's differ
  // by angle: one pass per sample.
  PlaneParts at_place[9];
  const bool per_place = !bank.has_shape();
  if (per_place) scorer.plane_parts_3x3(bank, ev[4].j, ux, uy, at_place);
  const double noise_var = noise_correction_ ? rss : 0.0;
  float plane_fs[kSamples];
  for (int i = 0; i < kSamples; ++i) {
    const int ox = kOffsets[i][0], oy = kOffsets[i][1];
    const PlaneParts q = per_place ? at_place[(ox + 1) + 3 * (oy + 1)]
                                   : scorer.plane_parts(bank, ev[i].j, ux + ox, uy + oy, ev[i].parts);
    if (!q.inside) return false;
    const double v = ev[i].parts.var - noise_var;
    if (!(v > 1e-9 * c.var)) return false;
    plane_fs[i] = static_cast<float>(std::sqrt(explained_with_plane(ev[i].parts, q, bank.plane_gram(ev[i].j)) / v));
  }
  std::copy(plane_fs, plane_fs + kSamples, fs);
  return true;
}

bool SubpixelFit::fit_at(ScoreCache& cache, int ux, int uy, int j, double& dx, double& dy, double& dj,
                         bool* plane_used) const noexcept {
  CachedScore ev[kSamples];
  for (int i = 0; i < kSamples; ++i) {
    ev[i] = cache.evaluate(j + kOffsets[i][2], ux + kOffsets[i][0], uy + kOffsets[i][1]);
    if (!ev[i].parts.inside) return false;
  }
  const ScoreParts& c = ev[4].parts;
  const double noise_var = noise_correction_ && c.tf > 0 ? std::max(0.0, c.var - c.tf * c.tf) : 0.0;
  float fs[kSamples];
  for (int i = 0; i < kSamples; ++i) {
    const double v = ev[i].parts.var - noise_var;
    if (!(v > 1e-9 * c.var) || !(ev[i].parts.var > 0.25 * ev[i].parts.count)) return false;
    fs[i] = static_cast<float>(ev[i].parts.tf / std::sqrt(v));
  }
  const bool plane = background_plane_ && c.tf > 0 && plane_scores(cache, ux, uy, ev, fs);
  if (plane_used) *plane_used = plane;
  float peak = 0;
  return joint_fit(fs, gaussian_, dx, dy, dj, peak) || (gaussian_ && joint_fit(fs, false, dx, dy, dj, peak));
}

}  // namespace sempose::pose
