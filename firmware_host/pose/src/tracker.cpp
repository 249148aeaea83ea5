// Tracker: glue between the correlator, the pattern banks and the tracking state machine.
#include "sempose/pose/tracker.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <string>

#include "sempose/pose/pattern_bank.hpp"
#include "sempose/pose/pose_filter.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/zncc.hpp"

namespace sempose::pose {

namespace {

double wrap_deg(double a) noexcept {
  a = std::fmod(a, 360.0);
  if (a <= -180.0) a += 360.0;
  if (a > 180.0) a -= 360.0;
  return a;
}

struct Peak {
  int ux = 0, uy = 0;
  float score = 0;
  float psr = 0;
  bool psr_valid = false;
};

struct Window {
  int x0 = 0, y0 = 0, x1 = 1 << 30, y1 = 1 << 30;  // inclusive search window in the map
};

// Maximum of a ZNCC map inside a window and its peak-to-sidelobe ratio (sidelobe = the whole
// map outside an 11×11 window around the peak).
Peak find_peak(const float* map, int vw, int vh, const Window& win = {}) noexcept {
  Peak p;
  p.score = -2.0f;
  const int ya = std::max(0, win.y0), yb = std::min(vh - 1, win.y1);
  const int xa = std::max(0, win.x0), xb = std::min(vw - 1, win.x1);
  p.ux = std::clamp(xa, 0, vw - 1);
  p.uy = std::clamp(ya, 0, vh - 1);
  for (int y = ya; y <= yb; ++y) {
    const float* row = map + static_cast<std::size_t>(y) * vw;
    for (int x = xa; x <= xb; ++x) {
      if (row[x] > p.score) {
        p.score = row[x];
        p.ux = x;
        p.uy = y;
      }
    }
  }
  double sum = 0, sum2 = 0;
  int count = 0;
  for (int y = 0; y < vh; ++y) {
    const float* row = map + static_cast<std::size_t>(y) * vw;
    const bool near_y = std::abs(y - p.uy) <= 5;
    for (int x = 0; x < vw; ++x) {
      if (near_y && std::abs(x - p.ux) <= 5) continue;
      sum += row[x];
      sum2 += static_cast<double>(row[x]) * row[x];
      ++count;
    }
  }
  if (count >= 20) {
    const double mean = sum / count;
    const double var = std::max(0.0, sum2 / count - mean * mean);
    const double sd = std::sqrt(var);
    p.psr = sd > 1e-6 ? static_cast<float>(std::clamp((p.score - mean) / sd, -1000.0, 1000.0)) : 1000.0f;
    p.psr_valid = true;
  }
  return p;
}

// Σ t·f over bands of the pattern: pattern t (P×P), image f at the window's top-left (row
// stride). The hot loop of every exact evaluation, cloned for AVX-512 / AVX2 (the build
// targets baseline x86-64). The bands are the mask's, widened to whole 16-float chunks
// (dot_bands): t is zero outside the mask, so the extra products add exactly nothing, and
// each chunk is one vector multiply-add into 16 lane sums reduced once at the end (a
// per-row horizontal reduction cost more than the products themselves).
__attribute__((target_clones("avx512f", "avx2", "default"))) double masked_dot(const float* t, int P, const float* f,
                                                                           std::ptrdiff_t stride, const MaskBand* bands,
                                                                           int n_bands) noexcept {
  constexpr int kLanes = 16;
  float lanes[kLanes] = {};
  float tail = 0;
  for (int k = 0; k < n_bands; ++k) {
    const MaskBand& b = bands[k];
    const int n = b.x1 - b.x0 + 1, n_vec = n / kLanes * kLanes;
    for (int y = b.y0; y <= b.y1; ++y) {
      const float* tr = t + static_cast<std::ptrdiff_t>(y) * P + b.x0;
      const float* fr = f + static_cast<std::ptrdiff_t>(y) * stride + b.x0;
      for (int x = 0; x < n_vec; x += kLanes) {
#pragma omp simd
        for (int l = 0; l < kLanes; ++l) lanes[l] += tr[x + l] * fr[x + l];
      }
      for (int x = n_vec; x < n; ++x) tail += tr[x] * fr[x];
    }
  }
  double total = tail;
  for (float v : lanes) total += v;
  return total;
}

// The mask's bands widened to whole 16-column chunks inside the pattern (see masked_dot),
// neighbouring bands with the same widened columns merged.
std::vector<MaskBand> dot_bands(const PatternMask& mask) {
  std::vector<MaskBand> out;
  const int P = mask.size_px();
  for (MaskBand b : mask.bands()) {
    b.x0 = b.x0 / 16 * 16;
    b.x1 = std::min(P - 1, (b.x1 / 16 + 1) * 16 - 1);
    if (!out.empty() && out.back().x0 == b.x0 && out.back().x1 == b.x1 && out.back().y1 + 1 == b.y0) {
      out.back().y1 = b.y1;
    } else {
      out.push_back(b);
    }
  }
  return out;
}

// Offset of a peak from three samples (left, centre, right), in (-0.5, 0.5).
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

}  // namespace

struct Measurement {
  bool valid = false;
  int j = 0;            // final angle index
  int ux = 0, uy = 0;   // integer displacement in the loaded region
  double dx = 0, dy = 0, dj = 0;  // sub-pixel / sub-step offsets
  float score = 0, psr = 0;
  bool psr_valid = false;
  int steps = 0;
  bool unsettled = false;
};

struct Tracker::Impl {
  config::TrackerConfig cfg;
  hal::ScanLimits limits;
  int P = 0, R = 0, N = 0, d = 8, Pc = 0, coarse_off = 0, n_angles = 360;
  double step = 1.0;
  PatternMask fine_mask, half_mask, coarse_mask;
  std::vector<MaskBand> fine_dot_bands;  // fine_mask widened for masked_dot
  // half: the whole ROI, 2×2 binned, correlated via FFT (finds the peak for every displacement);
  // the exact full-resolution ZNCC is then evaluated around it (local_parts).
  std::unique_ptr<ZnccCorrelator> half, coarse;
  int Nh = 0;
  std::vector<float> roi_img;          // prefiltered ROI minus its mean, full resolution (row stride roi_w)
  // Exact summed-area tables of the prefiltered ROI and its square ((roi_h+1)×(roi_w+1)): the
  // window mean and variance under the mask bands in a few look-ups, so the exact local ZNCC
  // costs one multiply-add per pixel.
  std::vector<std::int64_t> sat1, sat2;
  std::vector<std::int32_t> binned;    // 2×2 sums of the prefiltered ROI
  int roi_w = 0, roi_h = 0;
  std::unique_ptr<Prefilter> prefilter;
  std::vector<std::int32_t> filtered;  // prefiltered ROI (N×N)
  std::vector<PatternBank> banks;
  std::vector<double> nm_per_px;
  std::vector<float> map_a, map_b;  // half-resolution ZNCC maps: work and best-so-far
  float* map_work = nullptr;
  float* map_best = nullptr;
  std::vector<float> cmap;
  std::vector<std::int32_t> coarse_img;
  int coarse_cap_w = 0, coarse_cap_h = 0;
  struct Candidate {
    int ux, uy, k;
    float score;
  };
  std::vector<Candidate> cands;
  int n_cands = 0;
  bool gaussian = true;

  // Tracking state.
  bool tracking = false;
  int weak_frames = 0;
  bool have_prev = false;
  double pose_x = 0, pose_y = 0, pose_phi = 0;
  double vx = 0, vy = 0, vphi = 0;
  double pred_x = 0, pred_y = 0, pred_phi = 0;
  // The last tracked angle survives a loss (a start search's tie-break between a target and
  // its 180° look-alike).
  bool have_last_phi = false;
  double last_phi = 0;
  double score_mean = 0;  // running mean of accepted scores (relative_score_threshold)
  bool have_score_mean = false;
  int field_w = 0, field_h = 0;
  PoseFilter filter;
  std::atomic<bool> reacquire{false};
  std::atomic<std::uint8_t> active{0};

  // The outer ring of the pattern is made up at setup (prefilter edges replicated: 2 px per
  // pass; bicubic rotation clamps its 2 px support at the square's edge): keep it out of the
  // mask, or those pixels pull the peak off the true pose by a few tenths of a pixel in the
  // pattern's own frame (a bias that turns with the target).
  static double mask_inset_px(const config::TrackerConfig& c) noexcept { return 2.0 + 2.0 * c.prefilter_passes; }

  Impl(const config::TrackerConfig& c, int pattern_px)
      : cfg(c),
        fine_mask(pattern_px, c.circular_mask, 8, mask_inset_px(c)),
        half_mask(pattern_px / 2, c.circular_mask, 8, mask_inset_px(c) / 2),
        coarse_mask(pattern_px / c.search_downsample, c.circular_mask),
        fine_dot_bands(dot_bands(fine_mask)),
        filter(c.filter) {
    build_fit();
  }

  // Joint sub-pixel / sub-step fit: a quadratic in (dx, dy, dj) — 10 coefficients, cross terms
  // included — least-squares over 19 exact scores around the integer maximum: the 3×3 position
  // neighbourhood at angle j and the 5-point crosses at j±1. Separate 3-point fits per axis
  // are biased whenever the peak is tilted (an edge at an angle couples x and y; content off
  // the pattern centre couples position and angle) by up to a few tenths of a pixel/degree.
  static constexpr int kFitSamples = 19, kFitTerms = 10;
  static constexpr int kFitOffsets[kFitSamples][3] = {
      {-1, -1, 0}, {0, -1, 0}, {1, -1, 0}, {-1, 0, 0}, {0, 0, 0}, {1, 0, 0}, {-1, 1, 0}, {0, 1, 0}, {1, 1, 0},
      {0, 0, -1},  {-1, 0, -1}, {1, 0, -1}, {0, -1, -1}, {0, 1, -1},
      {0, 0, 1},   {-1, 0, 1},  {1, 0, 1},  {0, -1, 1},  {0, 1, 1}};
  double fit_pinv[kFitTerms][kFitSamples] = {};

  static void fit_terms(double x, double y, double j, double* t) noexcept {
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

  // Setup: (AᵀA)⁻¹Aᵀ of the fixed 19-sample design, by Gauss-Jordan elimination.
  void build_fit() noexcept {
    double a[kFitSamples][kFitTerms];
    for (int i = 0; i < kFitSamples; ++i) fit_terms(kFitOffsets[i][0], kFitOffsets[i][1], kFitOffsets[i][2], a[i]);
    double m[kFitTerms][2 * kFitTerms] = {};
    for (int r = 0; r < kFitTerms; ++r) {
      for (int c = 0; c < kFitTerms; ++c)
        for (int i = 0; i < kFitSamples; ++i) m[r][c] += a[i][r] * a[i][c];
      m[r][kFitTerms + r] = 1;
    }
    for (int c = 0; c < kFitTerms; ++c) {
      int piv = c;
      for (int r = c + 1; r < kFitTerms; ++r)
        if (std::fabs(m[r][c]) > std::fabs(m[piv][c])) piv = r;
      for (int k = 0; k < 2 * kFitTerms; ++k) std::swap(m[c][k], m[piv][k]);
      const double pv = m[c][c];
      for (int k = 0; k < 2 * kFitTerms; ++k) m[c][k] /= pv;
      for (int r = 0; r < kFitTerms; ++r) {
        if (r == c) continue;
        const double f = m[r][c];
        for (int k = 0; k < 2 * kFitTerms; ++k) m[r][k] -= f * m[c][k];
      }
    }
    for (int r = 0; r < kFitTerms; ++r)
      for (int i = 0; i < kFitSamples; ++i) {
        double v = 0;
        for (int c = 0; c < kFitTerms; ++c) v += m[r][kFitTerms + c] * a[i][c];
        fit_pinv[r][i] = v;
      }
  }

  // Peak of the fitted quadratic: solves H·u = −g. False when the surface is not a clear
  // maximum (H not negative definite) or the peak lies outside the sampled cube.
  bool joint_fit(const float* s, bool log_scores, double& dx, double& dy, double& dj, float& peak) const noexcept {
    double v[kFitSamples];
    for (int i = 0; i < kFitSamples; ++i) {
      if (s[i] <= -2.0f) return false;
      if (log_scores && s[i] <= 0.0f) return false;
      v[i] = log_scores ? std::log(static_cast<double>(s[i])) : s[i];
    }
    double q[kFitTerms];
    for (int r = 0; r < kFitTerms; ++r) {
      double acc = 0;
      for (int i = 0; i < kFitSamples; ++i) acc += fit_pinv[r][i] * v[i];
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
    double t[kFitTerms];
    fit_terms(ux, uy, uj, t);
    double val = 0;
    for (int r = 0; r < kFitTerms; ++r) val += q[r] * t[r];
    peak = static_cast<float>(log_scores ? std::exp(val) : val);
    return true;
  }

  int wrap_j(int j) const noexcept {
    j %= n_angles;
    return j < 0 ? j + n_angles : j;
  }
  int angle_index(double deg) const noexcept { return wrap_j(static_cast<int>(std::lround(deg / step))); }

  // Exact full-resolution correlation of angle j's pattern at displacement (ux, uy) of the
  // loaded ROI, window mean and variance under the mask computed in the same pass:
  // tf = Σ t·f (t zero-mean, unit norm) and var = Σ f² − (Σ f)²/n. False outside the ROI.
  bool local_parts(int j_pattern, const PatternBank& bank, int ux, int uy, double& tf_out, double& var_out,
                   double& count_out) const noexcept {
    if (ux < 0 || uy < 0 || ux > roi_w - P || uy > roi_h - P) return false;
    const float* t = bank.pattern(j_pattern);
    const std::size_t sw = static_cast<std::size_t>(roi_w) + 1;
    std::int64_t s1 = 0, s2 = 0;
    // The window's sums over this angle's support (the circle, or the turned shape mask).
    const MaskBand* bands = bank.support_bands(j_pattern);
    const int n_bands = bank.support_band_count(j_pattern);
    for (int k = 0; k < n_bands; ++k) {
      const MaskBand& b = bands[k];
      const std::size_t ya = static_cast<std::size_t>(uy + b.y0) * sw, yb = static_cast<std::size_t>(uy + b.y1 + 1) * sw;
      const std::size_t xa = static_cast<std::size_t>(ux + b.x0), xb = static_cast<std::size_t>(ux + b.x1 + 1);
      s1 += sat1[yb + xb] - sat1[yb + xa] - sat1[ya + xb] + sat1[ya + xa];
      s2 += sat2[yb + xb] - sat2[yb + xa] - sat2[ya + xb] + sat2[ya + xa];
    }
    // The pattern is zero outside its support, so the dot product may run over the whole
    // (chunk-widened) circle.
    const double tf = masked_dot(t, P, roi_img.data() + static_cast<std::size_t>(uy) * roi_w + ux, roi_w,
                                 fine_dot_bands.data(), static_cast<int>(fine_dot_bands.size()));
    // Σt = 0 under the support, so Σ t·(f − mean) = Σ t·f for any offset of f.
    tf_out = tf;
    const double n = static_cast<double>(bank.support_count(j_pattern));
    count_out = n;
    var_out = static_cast<double>(s2) - static_cast<double>(s1) * static_cast<double>(s1) / n;
    return true;
  }
  // ZNCC from the parts; a flat window (std under half a filtered unit) scores 0.
  static float zncc(double tf, double var, double count) noexcept {
    if (!(var > 0.25 * count)) return 0.0f;
    return static_cast<float>(std::clamp(tf / std::sqrt(var), -1.0, 1.0));
  }

  // One refine()'s exact evaluations, remembered: the climb, the walk and the fit revisit
  // the same (angle, displacement) many times.
  struct Eval {
    int j = 0, x = 0, y = 0;
    bool inside = false;
    double tf = 0, var = 0, count = 0;
    float score = -2.0f;
  };
  struct EvalMemo {
    std::array<Eval, 64> e;
    int n = 0, next = 0, computed = 0;
  };
  Eval evaluate(EvalMemo& memo, const PatternBank& bank, int j, int x, int y) const noexcept {
    j = wrap_j(j);
    for (int i = 0; i < memo.n; ++i) {
      const Eval& c = memo.e[static_cast<std::size_t>(i)];
      if (c.j == j && c.x == x && c.y == y) return c;
    }
    Eval v;
    v.j = j;
    v.x = x;
    v.y = y;
    v.inside = local_parts(j, bank, x, y, v.tf, v.var, v.count);
    v.score = v.inside ? zncc(v.tf, v.var, v.count) : -2.0f;
    ++memo.computed;
    memo.e[static_cast<std::size_t>(memo.next)] = v;
    memo.next = (memo.next + 1) % static_cast<int>(memo.e.size());
    memo.n = std::max(memo.n, memo.next == 0 ? static_cast<int>(memo.e.size()) : memo.next);
    return v;
  }

  // The joint fit around (ux, uy, j). The window variance of a noisy frame is signal plus
  // noise, and ZNCC = Σtf/√(signal+noise) leans towards displacements whose window holds
  // more signal variance (and, for shot noise, more noise) — a bias that turns with the
  // target. The fit therefore uses Σtf/√(var − noise var), with the noise variance taken
  // from the best match itself (var₀ − (Σtf)₀²: what the pattern does not explain there).
  bool fit_at(EvalMemo& memo, const PatternBank& bank, int ux, int uy, int j, double& dx, double& dy, double& dj) const noexcept {
    Eval ev[kFitSamples];
    for (int i = 0; i < kFitSamples; ++i) {
      ev[i] = evaluate(memo, bank, j + kFitOffsets[i][2], ux + kFitOffsets[i][0], uy + kFitOffsets[i][1]);
      if (!ev[i].inside) return false;
    }
    const Eval& c = ev[4];
    const double noise_var = cfg.fit_noise_correction && c.tf > 0 ? std::max(0.0, c.var - c.tf * c.tf) : 0.0;
    float fs[kFitSamples];
    for (int i = 0; i < kFitSamples; ++i) {
      const double v = ev[i].var - noise_var;
      if (!(v > 1e-9 * c.var) || !(ev[i].var > 0.25 * ev[i].count)) return false;
      fs[i] = static_cast<float>(ev[i].tf / std::sqrt(v));
    }
    float peak = 0;
    return joint_fit(fs, gaussian, dx, dy, dj, peak) || (gaussian && joint_fit(fs, false, dx, dy, dj, peak));
  }

  // From the half-resolution peak: full-resolution hill-climb in position, the paper's
  // orientation walk (j, j±1, move to the best until the centre wins, bounded), then the
  // joint sub-pixel / sub-step fit on exact full-resolution scores.
  Measurement refine(const PatternBank& bank, int j, const Peak& pk, int max_moves) noexcept {
    Measurement m;
    m.valid = true;
    m.psr = pk.psr;
    m.psr_valid = pk.psr_valid;
    int ux = 2 * pk.ux, uy = 2 * pk.uy;
    EvalMemo memo;
    auto score = [&](int jj, int x, int y) { return evaluate(memo, bank, jj, x, y).score; };
    // Position hill-climb at angle j (the binned peak is within a pixel or two).
    auto climb = [&](int jj) {
      for (int it = 0; it < 5; ++it) {
        int best = 4;
        float best_s = score(jj, ux, uy);
        for (int k = 0; k < 9; ++k) {
          const float sk = score(jj, ux + k % 3 - 1, uy + k / 3 - 1);
          if (sk > best_s) best_s = sk, best = k;
        }
        if (best == 4) return;
        ux += best % 3 - 1;
        uy += best / 3 - 1;
      }
    };
    climb(j);
    float s0 = score(j, ux, uy);
    float sm = score(j - 1, ux, uy);
    float sp = score(j + 1, ux, uy);
    int moves = 0;
    const int j_start = j;
    while (!(s0 >= sm && s0 >= sp)) {
      if (moves >= max_moves) {
        m.unsettled = true;
        break;
      }
      if (sp > sm) {
        sm = s0;
        s0 = sp;
        ++j;
        sp = score(j + 1, ux, uy);
      } else {
        sp = s0;
        s0 = sm;
        --j;
        sm = score(j - 1, ux, uy);
      }
      ++moves;
    }
    if (j != j_start) climb(j);  // the angle moved: the position's neighbourhood at the new angle
    // Joint fit; when its peak lies more than half a step away (a tie in the climb or the
    // walk), recentre on the nearest grid point once and fit again.
    bool fitted = false;
    for (int pass = 0; pass < 2; ++pass) {
      double dx = 0, dy = 0, dj = 0;
      if (!fit_at(memo, bank, ux, uy, j, dx, dy, dj)) break;
      fitted = true;
      m.dx = std::clamp(dx, -1.0, 1.0);
      m.dy = std::clamp(dy, -1.0, 1.0);
      m.dj = std::clamp(dj, -1.0, 1.0);
      if (pass == 1 || (std::fabs(dx) <= 0.6 && std::fabs(dy) <= 0.6 && std::fabs(dj) <= 0.6)) break;
      const int sx = static_cast<int>(std::lround(dx)), sy = static_cast<int>(std::lround(dy));
      const int sj = static_cast<int>(std::lround(dj));
      if (score(j + sj, ux + sx, uy + sy) < score(j, ux, uy)) break;
      ux += sx;
      uy += sy;
      j += sj;
      m.dx = std::clamp(dx - sx, -1.0, 1.0);
      m.dy = std::clamp(dy - sy, -1.0, 1.0);
      m.dj = std::clamp(dj - sj, -1.0, 1.0);
    }
    s0 = score(j, ux, uy);
    if (!fitted) {
      // No clear quadratic maximum (edge of the ROI, a ridge): separate 3-point fits.
      const float l = score(j, ux - 1, uy), r = score(j, ux + 1, uy);
      const float up = score(j, ux, uy - 1), dn = score(j, ux, uy + 1);
      sm = score(j - 1, ux, uy);
      sp = score(j + 1, ux, uy);
      m.dx = (l > -2.0f && r > -2.0f) ? fit3(l, s0, r, gaussian) : 0.0;
      m.dy = (up > -2.0f && dn > -2.0f) ? fit3(up, s0, dn, gaussian) : 0.0;
      m.dj = (sm > -2.0f && sp > -2.0f) ? fit3(sm, s0, sp, false) : 0.0;
    }
    m.steps += memo.computed;
    m.j = wrap_j(j);
    m.ux = ux;
    m.uy = uy;
    m.score = s0;
    return m;
  }

  // FFT correlations at angles centre ± window every sweep step (always including centre),
  // best map kept; then the walk from the best angle.
  Measurement sweep(const PatternBank& bank, int j_centre, double window_deg, double step_deg, int max_moves,
                    const Window& win = {}) noexcept {
    const int stride = std::max(1, static_cast<int>(std::lround(step_deg / step)));
    const int half_count = static_cast<int>(std::floor(window_deg / step / stride + 1e-9));
    Peak best;
    best.score = -3.0f;
    int best_j = j_centre;
    int ffts = 0;
    for (int i = -half_count; i <= half_count; ++i) {
      const int j = wrap_j(j_centre + i * stride);
      half->correlate(bank.spectrum(j), map_work);
      ++ffts;
      const Peak pk = find_peak(map_work, half->valid_w(), half->valid_h(), win);
      if (pk.score > best.score) {
        best = pk;
        best_j = j;
        std::swap(map_work, map_best);
      }
    }
    Measurement m = refine(bank, best_j, best, max_moves);
    m.steps += ffts;
    return m;
  }

  // Full-field start search over a w×h frame (row stride in px). Result in frame coordinates.
  Measurement search(const PatternBank& bank, const hal::Pixel* px, int w, int h, int bits, int& roi_x,
                     int& roi_y) noexcept {
    Measurement none;
    const int cw = std::min(w / d, coarse_cap_w), ch = std::min(h / d, coarse_cap_h);
    if (cw < Pc || ch < Pc) return none;
    for (int y = 0; y < ch; ++y) {
      std::int32_t* out = coarse_img.data() + static_cast<std::size_t>(y) * cw;
      for (int x = 0; x < cw; ++x) out[x] = 0;
      for (int j = 0; j < d; ++j) {
        const hal::Pixel* row = px + static_cast<std::size_t>(y * d + j) * w;
        for (int x = 0; x < cw; ++x) {
          std::int32_t acc = 0;
          for (int i = 0; i < d; ++i) acc += row[x * d + i];
          out[x] += acc;
        }
      }
    }
    if (!coarse->load(coarse_img.data(), cw, ch, cw)) return none;
    n_cands = 0;
    const int vw = coarse->valid_w(), vh = coarse->valid_h();
    const int sep = std::max(2, Pc / 2);
    for (int k = 0; k < bank.coarse_angles(); ++k) {
      coarse->correlate(bank.coarse_spectrum(k), cmap.data());
      for (int y = 0; y < vh; ++y) {
        for (int x = 0; x < vw; ++x) {
          const float s = cmap[static_cast<std::size_t>(y) * vw + x];
          if (s <= 0.0f) continue;
          if (n_cands == static_cast<int>(cands.size()) && s <= cands[n_cands - 1].score) continue;
          bool local_max = true;
          for (int j = -1; j <= 1 && local_max; ++j) {
            for (int i = -1; i <= 1; ++i) {
              const int xx = x + i, yy = y + j;
              if ((i || j) && xx >= 0 && yy >= 0 && xx < vw && yy < vh &&
                  cmap[static_cast<std::size_t>(yy) * vw + xx] > s) {
                local_max = false;
                break;
              }
            }
          }
          if (local_max) insert_candidate({x, y, k, s}, sep);
        }
      }
    }
    Measurement best;
    best.score = -2.0f;
    float best_rank = -10.0f;
    const int rw = std::min(R, w), rh = std::min(R, h);
    const int max_moves = static_cast<int>(std::ceil(cfg.search_refine_step_deg / step)) + 2;
    for (int c = 0; c < n_cands; ++c) {
      const Candidate& cd = cands[c];
      const double cx = cd.ux * d - coarse_off + (P - 1) / 2.0;
      const double cy = cd.uy * d - coarse_off + (P - 1) / 2.0;
      const int rx = std::clamp(static_cast<int>(std::lround(cx - (rw - 1) / 2.0)), 0, w - rw);
      const int ry = std::clamp(static_cast<int>(std::lround(cy - (rh - 1) / 2.0)), 0, h - rh);
      if (!load_roi(px + static_cast<std::size_t>(ry) * w + rx, rw, rh, w, bits)) continue;
      // The coarse position is good to about ±d/2 px: look for the fine peak only near it, so
      // that at low dose a chance peak elsewhere in the ROI cannot outscore the target.
      const int ex = static_cast<int>(std::lround(cx - (P - 1) / 2.0)) - rx;
      const int ey = static_cast<int>(std::lround(cy - (P - 1) / 2.0)) - ry;
      const Window win{(ex - d - 2) / 2, (ey - d - 2) / 2, (ex + d + 3) / 2, (ey + d + 3) / 2};  // binned px
      Measurement m = sweep(bank, angle_index(bank.coarse_angle_deg(cd.k)), cfg.search_refine_window_deg,
                            cfg.search_refine_step_deg, max_moves, win);
      // The coarse level keeps one angle per place, and elongated targets (a needle, a
      // lamella) look much alike turned by 180° at ×8 and a few electrons per pixel: try the
      // opposite angle too. Turned about the pattern's centre, the look-alike sits elsewhere
      // (twice the offset of the target's own centre from the pattern's centre, up to a
      // quarter pattern), so the opposite angle gets its own position search: one binned FFT
      // at φ+180° around the match, then the climb, the walk and the fit; the better exact
      // full-resolution score wins.
      if (m.valid) {
        const int jf = wrap_j(m.j + n_angles / 2);
        half->correlate(bank.spectrum(jf), map_work);
        const int reach = P / 8;  // binned px: a quarter pattern at full resolution
        const Window around{m.ux / 2 - reach, m.uy / 2 - reach, m.ux / 2 + reach, m.uy / 2 + reach};
        const Peak pk = find_peak(map_work, half->valid_w(), half->valid_h(), around);
        Measurement f = refine(bank, jf, pk, max_moves);
        f.steps += m.steps + 1;
        if (f.valid && prefer_opposite(m, f)) m = f;
        else m.steps = f.steps;
      }
      // Rank by coarse + fine score: the ×8 level averages 64 pixels per sample and is the
      // more discriminative statistic at a few electrons per pixel; the fine level refines.
      if (m.valid && m.score + cd.score > best_rank) {
        best_rank = m.score + cd.score;
        best = m;
        roi_x = rx;
        roi_y = ry;
      }

    }
    return best;
  }

  // Exact scores of a target and its 180° look-alike within kFlipTieScore of each other are a
  // tie at a few electrons per pixel (measured on the simulated lamellae: wrong-way-round
  // leads of 0.003–0.016 at doses 1–6 e⁻/px; the true flip of lamella_post at 2.5 e⁻/px
  // leads by 0.03). A target that was being tracked has not turned by 180° meanwhile: a tie
  // goes to the angle within kFlipPriorDeg of the last tracked one (a last pose from a torn
  // frame can be far off: no prior then), else stays with the coarse level's choice (m).
  static constexpr float kFlipTieScore = 0.02f;
  static constexpr double kFlipPriorDeg = 45.0;
  bool prefer_opposite(const Measurement& m, const Measurement& f) const noexcept {
    if (std::fabs(f.score - m.score) >= kFlipTieScore) return f.score > m.score;
    return have_last_phi && std::fabs(wrap_deg(f.j * step - last_phi)) < kFlipPriorDeg;
  }

  void insert_candidate(const Candidate& c, int sep) noexcept {
    for (int i = 0; i < n_cands; ++i) {
      if (std::abs(cands[i].ux - c.ux) < sep && std::abs(cands[i].uy - c.uy) < sep) {
        if (cands[i].score >= c.score) return;
        cands[i] = c;
        std::sort(cands.begin(), cands.begin() + n_cands, [](const Candidate& a, const Candidate& b) {
          return a.score > b.score;
        });
        return;
      }
    }
    if (n_cands < static_cast<int>(cands.size())) {
      cands[n_cands++] = c;
    } else {
      cands[n_cands - 1] = c;
    }
    for (int i = n_cands - 1; i > 0 && cands[i].score > cands[i - 1].score; --i) std::swap(cands[i], cands[i - 1]);
  }

  // Prefilter the ROI, keep it at full resolution (minus its mean, for local_parts), bin it
  // 2×2 and load the binned image into the half-resolution correlator (one forward FFT).
  bool load_roi(const hal::Pixel* px, int w, int h, std::ptrdiff_t stride, int bits) noexcept {
    w = std::min(w, N);
    h = std::min(h, N);
    roi_w = w;
    roi_h = h;
    prefilter->apply(px, w, h, stride, bits, filtered.data());
    const std::size_t sw = static_cast<std::size_t>(w) + 1;
    for (std::size_t x = 0; x < sw; ++x) sat1[x] = sat2[x] = 0;
    for (int y = 0; y < h; ++y) {
      std::int64_t r1 = 0, r2 = 0;
      const std::int32_t* row = filtered.data() + static_cast<std::size_t>(y) * w;
      std::int64_t* o1 = sat1.data() + static_cast<std::size_t>(y + 1) * sw;
      std::int64_t* o2 = sat2.data() + static_cast<std::size_t>(y + 1) * sw;
      const std::int64_t* p1 = o1 - sw;
      const std::int64_t* p2 = o2 - sw;
      o1[0] = o2[0] = 0;
      for (int x = 0; x < w; ++x) {
        r1 += row[x];
        r2 += static_cast<std::int64_t>(row[x]) * row[x];
        o1[x + 1] = p1[x + 1] + r1;
        o2[x + 1] = p2[x + 1] + r2;
      }
    }
    // The ROI's mean from the table's corner (exact; a running double sum is a serial chain
    // of dependent adds and cost more than the table).
    const std::size_t n = static_cast<std::size_t>(w) * h;
    const float mean = static_cast<float>(static_cast<double>(sat1[static_cast<std::size_t>(h) * sw + w]) / static_cast<double>(n));
    for (std::size_t i = 0; i < n; ++i) roi_img[i] = static_cast<float>(filtered[i]) - mean;
    const int bw = w / 2, bh = h / 2;
    for (int y = 0; y < bh; ++y) {
      const std::int32_t* r0 = filtered.data() + static_cast<std::size_t>(2 * y) * w;
      const std::int32_t* r1 = r0 + w;
      std::int32_t* o = binned.data() + static_cast<std::size_t>(y) * bw;
      for (int x = 0; x < bw; ++x) o[x] = (r0[2 * x] + r0[2 * x + 1] + r1[2 * x] + r1[2 * x + 1]) >> 2;
    }
    return half->load(binned.data(), bw, bh, bw);
  }

  // A score far below the target's recent scores is a look-alike, not the target (after a
  // jump the old ROI still holds texture that can beat the absolute threshold).
  bool below_recent(const Measurement& m) const noexcept {
    return cfg.relative_score_threshold > 0 && have_score_mean && m.score < cfg.relative_score_threshold * score_mean;
  }
  bool weak(const Measurement& m) const noexcept {
    return !m.valid || m.score < cfg.score_threshold || below_recent(m) ||
           (cfg.psr_threshold > 0 && m.psr_valid && m.psr < cfg.psr_threshold);
  }
  std::uint8_t weak_bits(const Measurement& m) const noexcept {
    std::uint8_t b = 0;
    if (!m.valid || m.score < cfg.score_threshold || below_recent(m)) b |= kReasonLowScore;
    if (cfg.psr_threshold > 0 && m.psr_valid && m.psr < cfg.psr_threshold) b |= kReasonLowPsr;
    return b;
  }

  void to_estimate(const Measurement& m, int origin_x, int origin_y, PoseEstimate& e) const noexcept {
    e.x_px = origin_x + m.ux + m.dx + (P - 1) / 2.0;
    e.y_px = origin_y + m.uy + m.dy + (P - 1) / 2.0;
    e.phi_deg = wrap_deg((m.j + m.dj) * step);
    e.meas_x_px = e.x_px;
    e.meas_y_px = e.y_px;
    e.meas_phi_deg = e.phi_deg;
    e.score = std::clamp(m.score, -1.0f, 1.0f);
    e.psr = m.psr;
    e.angle_steps = m.steps;
  }

  void go_lost() noexcept {
    filter.reset();
    tracking = false;
    have_score_mean = false;
    have_prev = false;
    weak_frames = 0;
    vx = vy = vphi = 0;
  }

  // The reported pose through the temporal filter (a pass-through unless tracker.filter is
  // on), timed at mid-scan: with a varying dwell the ROI's centre is scanned mid-frame.
  void filter_output(PoseEstimate& e, const hal::FrameMeta& meta, bool fresh) noexcept {
    if (fresh) filter.reset();
    const double t_s = 0.5e-9 * (static_cast<double>(meta.t_scan_start_ns) + static_cast<double>(meta.t_scan_end_ns));
    const PoseSample f = filter.update({t_s, e.x_px, e.y_px, e.phi_deg});
    e.x_px = f.x_px;
    e.y_px = f.y_px;
    e.phi_deg = f.phi_deg;
  }

  void accept(const PoseEstimate& e, bool fresh) noexcept {
    if (!fresh && have_prev) {
      vx = e.x_px - pose_x;
      vy = e.y_px - pose_y;
      vphi = wrap_deg(e.phi_deg - pose_phi);
    } else {
      vx = vy = vphi = 0;
    }
    pose_x = e.x_px;
    pose_y = e.y_px;
    pose_phi = e.phi_deg;
    last_phi = e.phi_deg;
    have_last_phi = true;
    score_mean = have_score_mean ? 0.8 * score_mean + 0.2 * e.score : e.score;
    have_score_mean = true;
    have_prev = true;
    tracking = true;
    weak_frames = 0;
    predict();
  }
  void predict() noexcept {
    const bool v = cfg.predict_velocity;
    pred_x = pose_x + (v ? vx : 0);
    pred_y = pose_y + (v ? vy : 0);
    pred_phi = wrap_deg(pose_phi + (v ? vphi : 0));
  }

  PoseEstimate update(const hal::FrameMeta& meta, const hal::Pixel* px) noexcept;
};

PoseEstimate Tracker::Impl::update(const hal::FrameMeta& meta, const hal::Pixel* px) noexcept {
  PoseEstimate e;
  const std::uint8_t set = active.load(std::memory_order_relaxed);
  e.pattern_set = set;
  e.x_px = pose_x;
  e.y_px = pose_y;
  e.phi_deg = pose_phi;
  if (meta.field_w > 0 && meta.field_h > 0) {
    field_w = meta.field_w;
    field_h = meta.field_h;
  }
  const int w = meta.roi.w, h = meta.roi.h;
  if (meta.status == hal::FrameStatus::kBad || px == nullptr || w <= 0 || h <= 0) {
    e.state = tracking ? TrackState::kLost : TrackState::kAcquiring;
    e.reason_bits = kReasonBadFrame;
    return e;
  }
  const PatternBank& bank = banks[set];
  const bool full_field = meta.roi.x == 0 && meta.roi.y == 0 && meta.roi.w >= field_w && meta.roi.h >= field_h;
  if (reacquire.exchange(false, std::memory_order_relaxed)) {
    go_lost();
    if (!full_field) {
      e.state = TrackState::kAcquiring;
      e.reason_bits = kReasonCommanded;
      return e;
    }
  }

  // A full-field frame while tracking (scanned before the last search's result reached the
  // scan plan): track in its crop at the predicted pose instead of searching again.
  int origin_x = meta.roi.x, origin_y = meta.roi.y, w_roi = w, h_roi = h;
  std::ptrdiff_t stride = w;
  if (full_field && tracking) {
    const int rw = std::min(R, w), rh = std::min(R, h);
    origin_x = std::clamp(static_cast<int>(std::lround(pred_x - (rw - 1) / 2.0)), 0, w - rw);
    origin_y = std::clamp(static_cast<int>(std::lround(pred_y - (rh - 1) / 2.0)), 0, h - rh);
    px += static_cast<std::size_t>(origin_y) * w + origin_x;
    w_roi = rw;
    h_roi = rh;
    origin_x += meta.roi.x;
    origin_y += meta.roi.y;
  }
  if (!tracking || w_roi > N || h_roi > N) {
    int rx = 0, ry = 0;
    e.searched = true;
    const Measurement m = search(bank, px, w, h, meta.bits, rx, ry);
    if (m.valid) to_estimate(m, meta.roi.x + rx, meta.roi.y + ry, e);
    if (m.valid && !weak(m)) {
      e.state = TrackState::kTracking;
      accept(e, true);
      filter_output(e, meta, true);
    } else {
      e.state = TrackState::kAcquiring;
      e.reason_bits = m.valid ? weak_bits(m) : static_cast<std::uint8_t>(kReasonFlatFrame);
      go_lost();
    }
    return e;
  }

  // Tracking: one forward FFT for this ROI, the predicted angle, the walk.
  if (w_roi < P || h_roi < P || !load_roi(px, w_roi, h_roi, stride, meta.bits)) {
    e.state = TrackState::kLost;
    e.reason_bits = static_cast<std::uint8_t>((w_roi < P || h_roi < P) ? kReasonOutOfField
                                                                                      : kReasonFlatFrame);
    e.score = 0;
    go_lost();
    return e;
  }
  const int max_moves = cfg.max_angle_steps_per_frame;
  const int j_pred = angle_index(pred_phi);
  half->correlate(bank.spectrum(j_pred), map_work);
  std::swap(map_work, map_best);
  Measurement m = refine(bank, j_pred, find_peak(map_best, half->valid_w(), half->valid_h()), max_moves);
  m.steps += 1;
  if ((weak(m) || m.unsettled) && cfg.recover_sweep_deg > 0) {
    // The walk hit its bound or the score collapsed: a bounded angle sweep in this ROI
    // before giving up (a fast spin or a slip in angle is recovered here, not followed).
    Measurement r = sweep(bank, m.unsettled ? m.j : j_pred, cfg.recover_sweep_deg, cfg.recover_step_deg, max_moves);
    r.steps += m.steps;
    if (r.score > m.score) m = r;
    else m.steps = r.steps;
  }
  to_estimate(m, origin_x, origin_y, e);
  if (m.unsettled) e.reason_bits |= kReasonAngleUnsettled;
  const double margin = 0.0;
  if (pred_x < margin || pred_y < margin || pred_x > field_w - 1 - margin || pred_y > field_h - 1 - margin) {
    e.reason_bits |= kReasonOutOfField;
  }
  if (!weak(m)) {
    e.state = TrackState::kTracking;
    accept(e, false);
    filter_output(e, meta, false);
    return e;
  }
  e.reason_bits |= weak_bits(m);
  if (++weak_frames >= cfg.lost_after_frames) {
    e.state = TrackState::kLost;
    go_lost();
  } else {
    // Not yet lost: report the measurement with its reasons, coast on the motion model.
    e.state = TrackState::kTracking;
    pose_x = pred_x;
    pose_y = pred_y;
    pose_phi = pred_phi;
    predict();
  }
  return e;
}

// ---------------------------------------------------------------------------------------

Tracker::Tracker(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Tracker::~Tracker() = default;

std::unique_ptr<Tracker> Tracker::create(const config::TrackerConfig& cfg, std::vector<PatternSet> sets,
                                         const hal::ScanLimits& limits, rt::Status& status) {
  auto fail = [&](std::string why) {
    status = rt::Status::failure("tracker: " + std::move(why));
    return std::unique_ptr<Tracker>();
  };
  if (sets.empty()) return fail("no pattern given (need at least one pattern set)");
  const int P = sets[0].image.width;
  for (std::size_t i = 0; i < sets.size(); ++i) {
    const hal::Image& im = sets[i].image;
    const std::string which = "pattern set " + std::to_string(i) + ": ";
    if (im.empty()) return fail(which + "the pattern image is empty");
    if (im.width != im.height)
      return fail(which + "the pattern is " + std::to_string(im.width) + "x" + std::to_string(im.height) +
                  "; patterns must be square");
    if (im.pixels.size() != static_cast<std::size_t>(im.width) * im.height)
      return fail(which + "pixel count does not match width x height");
    if (im.width != P)
      return fail(which + "is " + std::to_string(im.width) + " px, pattern set 0 is " + std::to_string(P) +
                  " px; all pattern sets of a target must have the same size");
    if (!(sets[i].nm_per_px > 0)) return fail(which + "nm_per_px must be > 0");
  }
  if (sets.size() > 255) return fail("at most 255 pattern sets");
  if (P > cfg.roi_size_px)
    return fail("the pattern (" + std::to_string(P) + " px) is larger than tracker.roi_size_px (" +
                std::to_string(cfg.roi_size_px) + " px)");
  if (P / cfg.search_downsample < 4)
    return fail("pattern of " + std::to_string(P) + " px with tracker.search_downsample " +
                std::to_string(cfg.search_downsample) + " leaves under 4 px at the coarse level");
  if (limits.field_w < P || limits.field_h < P) return fail("the scan field is smaller than the pattern");
  const double steps = 360.0 / cfg.angle_step_deg;
  if (!(cfg.angle_step_deg > 0) || std::fabs(steps - std::round(steps)) > 1e-6)
    return fail("tracker.angle_step_deg " + std::to_string(cfg.angle_step_deg) + " must divide 360");

  auto impl = std::make_unique<Impl>(cfg, P);
  Impl& t = *impl;
  t.limits = limits;
  t.P = P;
  t.R = std::min({cfg.roi_size_px, limits.field_w, limits.field_h});
  t.N = good_fft_size(t.R);
  t.d = cfg.search_downsample;
  t.Pc = P / t.d;
  t.coarse_off = (P - t.Pc * t.d) / 2;
  t.step = cfg.angle_step_deg;
  t.n_angles = static_cast<int>(std::lround(steps));
  t.gaussian = cfg.subpixel == "gaussian";
  t.field_w = limits.field_w;
  t.field_h = limits.field_h;
  t.coarse_cap_w = std::max(t.Pc, limits.field_w / t.d);
  t.coarse_cap_h = std::max(t.Pc, limits.field_h / t.d);
  t.Nh = good_fft_size(t.N / 2);
  t.half = std::make_unique<ZnccCorrelator>(t.Nh, t.Nh, t.half_mask);
  t.coarse = std::make_unique<ZnccCorrelator>(good_fft_size(t.coarse_cap_w), good_fft_size(t.coarse_cap_h),
                                              t.coarse_mask);
  t.prefilter = std::make_unique<Prefilter>(cfg.prefilter_passes, t.N, t.N);
  t.filtered.assign(static_cast<std::size_t>(t.N) * t.N, 0);
  t.banks.resize(sets.size());
  for (std::size_t i = 0; i < sets.size(); ++i) {
    std::string why;
    if (!t.banks[i].build(sets[i].image, sets[i].mask, cfg.shape_mask_margin_px, cfg.prefilter_passes, t.step, t.fine_mask, t.half_mask, *t.half, cfg.search_angle_step_deg, t.d,
                          t.coarse_mask, *t.coarse, why))
      return fail("pattern set " + std::to_string(i) + ": " + why);
    t.nm_per_px.push_back(sets[i].nm_per_px);
  }
  const std::size_t vmax = static_cast<std::size_t>(t.Nh) * t.Nh;
  t.roi_img.assign(static_cast<std::size_t>(t.N) * t.N, 0.0f);
  t.sat1.assign(static_cast<std::size_t>(t.N + 1) * (t.N + 1), 0);
  t.sat2.assign(t.sat1.size(), 0);
  t.binned.assign(vmax, 0);
  t.map_a.assign(vmax, 0.0f);
  t.map_b.assign(vmax, 0.0f);
  t.map_work = t.map_a.data();
  t.map_best = t.map_b.data();
  t.cmap.assign(static_cast<std::size_t>(t.coarse_cap_w) * t.coarse_cap_h, 0.0f);
  t.coarse_img.assign(static_cast<std::size_t>(t.coarse_cap_w) * t.coarse_cap_h, 0);
  t.cands.assign(static_cast<std::size_t>(cfg.search_candidates), {0, 0, 0, 0.0f});
  status = rt::Status::success();
  if (t.half->execute_allocates() || t.coarse->execute_allocates()) {
    status.message = "tracker: warning: no allocation-free FFTW plan found for " + std::to_string(t.N) +
                     "x" + std::to_string(t.N) + " or the coarse size; the loop may call malloc";
  }
  return std::unique_ptr<Tracker>(new Tracker(std::move(impl)));
}

hal::Roi Tracker::next_roi() const noexcept {
  const Impl& t = *impl_;
  if (!t.tracking || t.reacquire.load(std::memory_order_relaxed)) return {0, 0, t.field_w, t.field_h};
  const int rw = std::min(t.R, t.field_w), rh = std::min(t.R, t.field_h);
  const int rx = std::clamp(static_cast<int>(std::lround(t.pred_x - (rw - 1) / 2.0)), 0, t.field_w - rw);
  const int ry = std::clamp(static_cast<int>(std::lround(t.pred_y - (rh - 1) / 2.0)), 0, t.field_h - rh);
  return {rx, ry, rw, rh};
}

PoseEstimate Tracker::update(const hal::FrameMeta& meta, const hal::Pixel* pixels) noexcept {
  return impl_->update(meta, pixels);
}

bool Tracker::select_pattern_set(std::uint8_t set) noexcept {
  if (set >= impl_->banks.size()) return false;
  if (impl_->active.exchange(set, std::memory_order_relaxed) != set) {
    // A new magnification changes the target's size on screen: find it again.
    impl_->reacquire.store(true, std::memory_order_relaxed);
  }
  return true;
}

std::uint8_t Tracker::pattern_set() const noexcept { return impl_->active.load(std::memory_order_relaxed); }
double Tracker::nm_per_px() const noexcept { return impl_->nm_per_px[impl_->active.load(std::memory_order_relaxed)]; }
void Tracker::request_reacquire() noexcept { impl_->reacquire.store(true, std::memory_order_relaxed); }

std::size_t Tracker::memory_bytes() const noexcept {
  const Impl& t = *impl_;
  std::size_t b = t.half->buffer_bytes() + t.coarse->buffer_bytes();
  b += t.roi_img.size() * sizeof(float) + t.binned.size() * sizeof(std::int32_t);
  b += (t.sat1.size() + t.sat2.size()) * sizeof(std::int64_t);
  for (const auto& bank : t.banks) b += bank.memory_bytes();
  b += (t.map_a.size() + t.map_b.size() + t.cmap.size()) * sizeof(float) + t.coarse_img.size() * 4;
  b += t.filtered.size() * 4 + static_cast<std::size_t>(t.N) * t.N * 16;  // prefilter scratch
  return b;
}

}  // namespace sempose::pose
