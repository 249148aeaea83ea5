#include "sempose/pose/pose_refinement.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/window_noise.hpp"
#include "sempose/rt/angle.hpp"

namespace sempose::pose {

namespace {

// `passes` separable 5-tap binomial low-passes (1 4 6 4 1)/16 of a P×P image, edges replicated
// (setup only).
void binomial_passes(std::vector<float>& img, int P, int passes) {
  std::vector<double> line(static_cast<std::size_t>(P) + 4);
  auto run = [&](float* p, std::ptrdiff_t step) {
    for (int i = 0; i < P; ++i) line[static_cast<std::size_t>(i) + 2] = p[i * step];
    line[0] = line[1] = line[2];
    line[static_cast<std::size_t>(P) + 2] = line[static_cast<std::size_t>(P) + 3] = line[static_cast<std::size_t>(P) + 1];
    for (int i = 0; i < P; ++i) {
      const double* q = &line[static_cast<std::size_t>(i)];
      p[i * step] = static_cast<float>((q[0] + 4 * q[1] + 6 * q[2] + 4 * q[3] + q[4]) / 16.0);
    }
  };
  for (int k = 0; k < passes; ++k) {
    for (int y = 0; y < P; ++y) run(&img[static_cast<std::size_t>(y) * P], 1);
    for (int x = 0; x < P; ++x) run(&img[static_cast<std::size_t>(x)], P);
  }
}

// Central-difference gradient energy terms of a P×P image over the inner pixels `inside`:
// Σ |∇a|² (aa) and Σ ∇a·∇b (ab).
void gradient_sums(const std::vector<float>& a, const std::vector<float>& b, int P, const std::vector<std::uint8_t>& inside,
                   double& aa, double& ab) {
  aa = ab = 0;
  for (int y = 1; y < P - 1; ++y)
    for (int x = 1; x < P - 1; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * P + x;
      if (!inside[i]) continue;
      const double ax = 0.5 * (a[i + 1] - a[i - 1]), ay = 0.5 * (a[i + P] - a[i - P]);
      const double bx = 0.5 * (b[i + 1] - b[i - 1]), by = 0.5 * (b[i + P] - b[i - P]);
      aa += ax * ax + ay * ay;
      ab += ax * bx + ay * by;
    }
}

}  // namespace

// template_passes auto: the passes p (0..kMaxAutoPasses) that minimise the variance of the fit's
// translation, V(p) ∝ Σ|∇T_p|² / (Σ ∇T_p·∇T_true)² (the frame's noise enters through the
// template's gradient ∇T_p, its own noise included; the signal through its overlap with the true
// gradient). Σ ∇T_p·∇T_true = Σ ∇T_p·∇T_0 − n·σ²·κ_p: the recorded pattern's noise (σ² by
// Immerkær's estimator over the pattern) correlates ∇T_p with ∇T_0 by κ_p, the overlap of the
// two filters' impulse responses. A noise-free pattern gives 0 passes.
int PoseRefinement::auto_template_passes(const PatternImage& recorded, const std::vector<std::uint8_t>& inside) {
  const int P = recorded.width;
  const double noise = window_noise_var(recorded.pixels.data(), P, 0, 0, P);
  std::vector<float> t0(recorded.pixels.begin(), recorded.pixels.end()), tp = t0;
  // κ_p from an impulse (a centred unit pixel; its filtered copies stay inside a 33² image).
  constexpr int kI = 33;
  std::vector<float> d0(static_cast<std::size_t>(kI) * kI, 0.0f);
  d0[static_cast<std::size_t>(kI / 2) * kI + kI / 2] = 1.0f;
  std::vector<float> dp = d0;
  const std::vector<std::uint8_t> all(d0.size(), 1);
  std::size_t n = 0;
  for (int y = 1; y < P - 1; ++y)
    for (int x = 1; x < P - 1; ++x) n += inside[static_cast<std::size_t>(y) * P + x] != 0;
  int best = 0;
  double best_v = -1;  // < 0: none yet (a pass whose gradient holds no signal is never chosen)
  for (int p = 0; p <= kMaxAutoPasses; ++p) {
    if (p > 0) {
      binomial_passes(tp, P, 1);
      binomial_passes(dp, kI, 1);
    }
    double aa, ab, kk, kappa;
    gradient_sums(tp, t0, P, inside, aa, ab);
    gradient_sums(dp, d0, kI, all, kk, kappa);
    const double signal = ab - static_cast<double>(n) * noise * kappa;
    if (!(signal > 0)) continue;
    const double v = aa / (signal * signal);
    if (best_v < 0 || v < best_v) {
      best = p;
      best_v = v;
    }
  }
  return best;
}

bool PoseRefinement::add_set(const PatternBank& bank, const PatternImage& recorded, int bits) {
  const int P = bank.size_px();
  std::vector<std::uint8_t> inside(static_cast<std::size_t>(P) * P, 0);
  for (int k = 0; k < bank.support_band_count(0); ++k) {
    const MaskBand& b = bank.support_bands(0)[k];
    for (int y = b.y0; y <= b.y1; ++y)
      for (int x = b.x0; x <= b.x1; ++x) inside[static_cast<std::size_t>(y) * P + x] = 1;
  }
  const config::RefineConfig& cfg = fit_.config();
  std::vector<float> img(bank.pattern(0), bank.pattern(0) + static_cast<std::size_t>(P) * P);
  const bool have_recorded = recorded.width == P && recorded.height == P &&
                             recorded.pixels.size() == static_cast<std::size_t>(P) * P;
  if (raw_ && have_recorded) {
    for (std::size_t i = 0; i < img.size(); ++i) img[i] = static_cast<float>(recorded.pixels[i]);
    const int passes = cfg.template_passes >= 0 ? cfg.template_passes : auto_template_passes(recorded, inside);
    binomial_passes(img, P, passes);
    passes_.push_back(passes);
  }
  // Noise weights: the detector's variance ∝ signal above the black level + the read noise's
  // share, the signal from the recorded pattern smoothed twice (so its own noise does not pick
  // the weights); at least 2 % of the mean signal over the support.
  std::vector<float> var;
  if (cfg.noise_weights && have_recorded) {
    var.assign(recorded.pixels.begin(), recorded.pixels.end());
    binomial_passes(var, P, 2);
    const double black = cfg.black_level * static_cast<double>((1u << std::clamp(bits, 1, 16)) - 1u);
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < var.size(); ++i) {
      var[i] = static_cast<float>(std::max(0.0, var[i] - black));
      if (inside[i]) {
        sum += var[i];
        ++n;
      }
    }
    const double floor = 0.02 * (n > 0 ? sum / static_cast<double>(n) : 0.0);
    for (float& v : var) v = static_cast<float>(std::max(static_cast<double>(v), floor) + cfg.read_noise_counts);
    if (!(floor + cfg.read_noise_counts > 0)) var.clear();  // a black pattern: no signal to weight by
  }
  if (passes_.size() < templates_.size() + 1) passes_.push_back(0);
  FitTemplate t;
  const bool ok = t.build(img.data(), P, inside.data(), var.empty() ? nullptr : var.data());
  templates_.push_back(std::move(t));
  return ok;
}

Measurement PoseRefinement::refine(std::uint8_t set, const PatternBank& bank, const Measurement& m,
                                   const RawRoi& raw) const noexcept {
  Measurement out = m;
  if (!fit_.config().enabled || !m.valid || set >= templates_.size()) return out;
  out.refine_status = static_cast<std::uint8_t>(FitStatus::kSkipped);
  if (!(m.score >= fit_.config().min_score)) return out;
  const double c = (bank.size_px() - 1) / 2.0;
  const FitPose start{m.ux + m.dx + c, m.uy + m.dy + c, (m.j + m.dj) * step_deg_, 1.0};
  const FitTemplate& tpl = templates_[set];
  const FitResult r = raw_ ? fit_.fit(tpl, raw.px, scorer_.roi_w(), scorer_.roi_h(), raw.stride, start)
                           : fit_.fit(tpl, scorer_.roi(), scorer_.roi_w(), scorer_.roi_h(), scorer_.roi_w(), start);
  out.refine_status = static_cast<std::uint8_t>(r.status);
  if (r.status != FitStatus::kRefined) return out;
  if (fit_.config().fit_position) {
    out.dx = r.pose.cx - c - m.ux;
    out.dy = r.pose.cy - c - m.uy;
  }
  if (fit_.config().fit_angle) {
    out.dj = rt::wrap_deg(r.pose.phi_deg - m.j * step_deg_) / step_deg_;
    out.refined_scale = static_cast<float>(r.pose.scale);
  }
  return out;
}

std::size_t PoseRefinement::memory_bytes() const noexcept {
  std::size_t b = 0;
  for (const FitTemplate& t : templates_) b += t.memory_bytes();
  return b;
}

}  // namespace sempose::pose
