// Learned appearance on synthetic input: a textured disc (the target) moves and turns over a
// textured background that is not the one the pattern was recorded over. The observer, fed
// the true poses, and the model must drop the background ring under the pattern's rim and keep
// the disc; the drift check must refuse batches observed at wrong poses or corrupted; the
// RT half allocates nothing; and in closed loop on the simulator the tracker learns, swaps
// banks and stays allocation-free.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "sempose/config/appearance_config.hpp"
#include "sempose/pose/appearance_model.hpp"
#include "sempose/pose/appearance_observer.hpp"
#include "sempose/pose/pattern_support.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sim_harness.hpp"

using namespace sempose;
using namespace sempose::pose;
using namespace sempose::pose::testing;

namespace {

constexpr int kP = 64;           // pattern side
constexpr double kDiscR = 20.0;  // the target's radius (the circle's is 28 after the inset)
constexpr int kRoi = 96;

// Smooth random texture: white noise box-blurred twice (3 px), zero mean, ~unit contrast.
std::vector<double> texture(int w, int h, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> a(static_cast<std::size_t>(w) * h), b(a.size());
  for (auto& v : a) v = g(rng);
  for (int pass = 0; pass < 2; ++pass) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        double s = 0;
        int n = 0;
        for (int dy = -3; dy <= 3; ++dy)
          for (int dx = -3; dx <= 3; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
            s += a[static_cast<std::size_t>(yy) * w + xx];
            ++n;
          }
        b[static_cast<std::size_t>(y) * w + x] = s / n * 2.6;  // back to ~unit contrast
      }
    a.swap(b);
  }
  return a;
}

// The scene: background texture bg (large), the disc's own texture in its frame.
struct Scene {
  int bw = 400, bh = 400;
  std::vector<double> bg = texture(400, 400, 11);
  std::vector<double> disc = texture(kP, kP, 29);
  double disc_r = kDiscR;
  // Bilinear sample of a w×h texture (edges clamped).
  static double bilinear(const std::vector<double>& t, int w, int h, double x, double y) {
    x = std::clamp(x, 0.0, w - 1.001);
    y = std::clamp(y, 0.0, h - 1.001);
    const int ix = static_cast<int>(x), iy = static_cast<int>(y);
    const double fx = x - ix, fy = y - iy;
    const double* r = t.data() + static_cast<std::size_t>(iy) * w + ix;
    return (1 - fy) * ((1 - fx) * r[0] + fx * r[1]) + fy * ((1 - fx) * r[w] + fx * r[w + 1]);
  }
  // Intensity at scene point (x, y) with the disc centred at (cx, cy), turned by phi.
  double at(double x, double y, double cx, double cy, double phi_deg) const {
    const double c = (kP - 1) / 2.0, r = phi_deg * M_PI / 180.0, cs = std::cos(r), sn = std::sin(r);
    const double dx = x - cx, dy = y - cy;
    // Inverse of the bank's map: output offset d shows source offset (dx·cos − dy·sin, dx·sin + dy·cos).
    const double sx = dx * cs - dy * sn, sy = dx * sn + dy * cs;
    if (sx * sx + sy * sy <= disc_r * disc_r) return 150 + 40 * bilinear(disc, kP, kP, c + sx, c + sy);
    return 100 + 40 * bilinear(bg, bw, bh, x, y);
  }
};

struct Fixture {
  Scene scene;
  PatternMask circle{kP, true, 8, 4.0};
  std::vector<float> reference;  // the pattern recorded at (100.5, 100.5), φ = 0, prefiltered
  std::vector<float> truth;      // the same without the recording's noise
  // disc_r: the target's radius (≥ 32: it covers the whole circle, no background under the
  // rim); recording_noise: SD of the recorded pattern's own noise (grey levels, white).
  explicit Fixture(double disc_r = kDiscR, double recording_noise = 0.0) {
    scene.disc_r = disc_r;
    std::vector<float> pat(static_cast<std::size_t>(kP) * kP);
    const double c = (kP - 1) / 2.0;
    for (int v = 0; v < kP; ++v)
      for (int u = 0; u < kP; ++u) pat[static_cast<std::size_t>(v) * kP + u] = static_cast<float>(scene.at(100.5 - c + u, 100.5 - c + v, 100.5, 100.5, 0));
    std::vector<float> clean = pat;
    std::mt19937 rng(77);
    std::normal_distribution<double> g(0.0, recording_noise > 0 ? recording_noise : 1.0);
    if (recording_noise > 0)
      for (auto& v : pat) v = static_cast<float>(v + g(rng));
    prefilter_pattern(pat.data(), kP, 1);
    prefilter_pattern(clean.data(), kP, 1);
    reference = pat;
    truth = clean;
  }
  // One ROI (kRoi², top-left at (ox, oy) of the scene) with the disc at (x, y, phi), Gaussian
  // noise of sd `noise`; its prefiltered copy minus mean into roi_f.
  void frame(double x, double y, double phi, int ox, int oy, double noise, std::mt19937& rng,
             std::vector<std::uint16_t>& raw, std::vector<float>& roi_f, Prefilter& pf) const {
    std::normal_distribution<double> g(0.0, noise);
    raw.resize(static_cast<std::size_t>(kRoi) * kRoi);
    for (int yy = 0; yy < kRoi; ++yy)
      for (int xx = 0; xx < kRoi; ++xx) {
        const double v = scene.at(ox + xx, oy + yy, x, y, phi) + g(rng);
        raw[static_cast<std::size_t>(yy) * kRoi + xx] = static_cast<std::uint16_t>(std::clamp(v, 0.0, 255.0));
      }
    std::vector<std::int32_t> filt(raw.size());
    pf.apply(raw.data(), kRoi, kRoi, kRoi, 8, filt.data());
    double mean = 0;
    for (auto v : filt) mean += v;
    mean /= static_cast<double>(filt.size());
    roi_f.resize(filt.size());
    for (std::size_t i = 0; i < filt.size(); ++i) roi_f[i] = static_cast<float>(filt[i] - mean);
  }
  double noise_gain() const {
    const double k[5] = {1 / 16.0, 4 / 16.0, 6 / 16.0, 4 / 16.0, 1 / 16.0};
    double g = 0;
    for (double v : k) g += v * v;
    return g * g;
  }
  // Frames along a path over new background; pose_error_px is added to the pose told to the
  // observer (a tracker reporting a wrong pose). Returns the batches the observer handed over.
  std::vector<AppearanceStats> observe(AppearanceObserver& obs, int frames, double pose_error_px, double noise,
                                       std::uint32_t seed, double angle_error_deg = 0.0, int first = 0) const {
    std::mt19937 rng(seed);
    Prefilter pf(1, kRoi, kRoi);
    std::vector<std::uint16_t> raw;
    std::vector<float> roi;
    std::vector<AppearanceStats> batches;
    for (int f = first; f < first + frames; ++f) {
      const double x = 120 + 4.3 * f, y = 140 + 2.1 * f, phi = 1.5 * f;  // moves 4.8 px/frame, turns
      const int ox = static_cast<int>(x) - kRoi / 2, oy = static_cast<int>(y) - kRoi / 2;
      frame(x, y, phi, ox, oy, noise, rng, raw, roi, pf);
      obs.observe(0, roi.data(), kRoi, kRoi, raw.data(), kRoi, 8, x - ox + pose_error_px, y - oy, phi + angle_error_deg,
                  x + pose_error_px, y);
      if (const AppearanceStats* b = obs.take()) {
        batches.push_back(*b);
        obs.give_back();
      }
    }
    return batches;
  }
  std::unique_ptr<AppearanceObserver> observer(int per_batch) const {
    auto o = std::make_unique<AppearanceObserver>(kP, circle.bitmap(), per_batch, noise_gain(), 1);
    o->add_reference(reference);
    return o;
  }
  AppearanceModel model(const config::AppearanceConfig& cfg) const {
    return AppearanceModel(cfg, kP, circle.bitmap(), {reference}, {std::vector<float>{}});
  }
  // RMS over the circle of a template against the noise-free recorded pattern.
  double error_vs_truth(const std::vector<float>& t) const {
    double s2 = 0, n = 0;
    for (int v = 0; v < kP; ++v)
      for (int u = 0; u < kP; ++u) {
        if (!circle.inside(u, v)) continue;
        const std::size_t i = static_cast<std::size_t>(v) * kP + u;
        s2 += (t[i] - truth[i]) * (t[i] - truth[i]);
        n += 1;
      }
    return std::sqrt(s2 / n);
  }
  // Share of the circle's pixels kept at distance in [r0, r1) from the centre.
  double kept(const std::vector<std::uint8_t>& support, double r0, double r1) const {
    const double c = (kP - 1) / 2.0;
    int in = 0, keep = 0;
    for (int v = 0; v < kP; ++v)
      for (int u = 0; u < kP; ++u) {
        const double r = std::hypot(u - c, v - c);
        if (!circle.inside(u, v) || r < r0 || r >= r1) continue;
        ++in;
        keep += support[static_cast<std::size_t>(v) * kP + u];
      }
    return in ? static_cast<double>(keep) / in : -1.0;
  }
};

}  // namespace

TEST(Appearance, LearnedSupportDropsTheChangingBackgroundRingAndKeepsTheTarget) {
  const Fixture fx;
  config::AppearanceConfig cfg;
  auto obs = fx.observer(16);
  AppearanceModel model = fx.model(cfg);
  const auto batches = fx.observe(*obs, 48, 0.0, 12.0, 5);
  ASSERT_GE(batches.size(), 2u);
  AppearanceDecision d;
  for (const auto& b : batches) {
    d = model.update(b);
    EXPECT_TRUE(d.accepted) << d.why;
  }
  ASSERT_TRUE(d.accepted);
  // Decisions are per 4×4 block (diagonal 5.7 px): blocks straddling the disc's edge go either way.
  const double disc = fx.kept(d.support, 0, kDiscR - 6), ring = fx.kept(d.support, kDiscR + 6, 40);
  std::printf("kept: disc interior %.2f, background ring %.2f, support %.2f of the circle, consistency %.3f, drift %.3f px\n",
              disc, ring, d.support_fraction, d.consistency, d.drift_px);
  // Not 1.0: the recorded pattern samples the disc's texture at its own pixels, the moving,
  // turning frames interpolate it (bilinear twice: scene and observer), which blurs the few
  // blocks of highest curvature beyond 2× the noise.
  EXPECT_GT(disc, 0.90);
  EXPECT_LT(ring, 0.10);
  EXPECT_LT(d.drift_px, 0.3);
}

TEST(Appearance, StaticSceneKeepsTheWholeCircle) {
  // The target does not move over its background: every pixel is explained, nothing is dropped
  // (ordinary noise must not thin the support).
  const Fixture fx;
  config::AppearanceConfig cfg;
  auto obs = fx.observer(16);
  AppearanceModel model = fx.model(cfg);
  std::mt19937 rng(9);
  Prefilter pf(1, kRoi, kRoi);
  std::vector<std::uint16_t> raw;
  std::vector<float> roi;
  AppearanceDecision d;
  for (int f = 0; f < 32; ++f) {
    fx.frame(100.5, 100.5, 0, 100 - kRoi / 2, 100 - kRoi / 2, 12.0, rng, raw, roi, pf);
    obs->observe(0, roi.data(), kRoi, kRoi, raw.data(), kRoi, 8, kRoi / 2 + 0.5, kRoi / 2 + 0.5, 0.0);
    if (const AppearanceStats* b = obs->take()) {
      d = model.update(*b);
      obs->give_back();
    }
  }
  ASSERT_TRUE(d.accepted) << d.why;
  EXPECT_GT(d.support_fraction, 0.97);
}

TEST(Appearance, DriftCheckRejectsObservationsAtWrongPosesAndCorruptedBatches) {
  const Fixture fx;
  config::AppearanceConfig cfg;
  {
    // A tracker 2.5 px off: the aligned mean is the pattern shifted; refused, nothing learnt.
    auto obs = fx.observer(16);
    AppearanceModel model = fx.model(cfg);
    const auto batches = fx.observe(*obs, 16, 2.5, 12.0, 7);
    ASSERT_EQ(batches.size(), 1u);
    const AppearanceDecision d = model.update(batches[0]);
    EXPECT_FALSE(d.accepted) << "drift " << d.drift_px << " consistency " << d.consistency;
    EXPECT_FALSE(d.why.empty());
    EXPECT_EQ(model.sums(0).frames, 0) << "a refused batch must not enter the sums";
  }
  {
    // A good batch corrupted afterwards (observations replaced by noise): refused; the same
    // batch uncorrupted is accepted (the check can pass).
    auto obs = fx.observer(16);
    AppearanceModel model = fx.model(cfg);
    const auto batches = fx.observe(*obs, 32, 0.0, 12.0, 8);
    ASSERT_EQ(batches.size(), 2u);
    AppearanceStats bad = batches[0];
    std::mt19937 rng(1);
    std::normal_distribution<double> g(0, 500);
    for (std::size_t i = 0; i < bad.sum_obs.size(); ++i) bad.sum_obs[i] = g(rng);
    EXPECT_FALSE(model.update(bad).accepted);
    const AppearanceDecision ok = model.update(batches[1]);
    EXPECT_TRUE(ok.accepted) << ok.why;
  }
}

TEST(Appearance, ObserverAllocatesNothing) {
  const Fixture fx;
  auto obs = fx.observer(4);
  std::mt19937 rng(3);
  Prefilter pf(1, kRoi, kRoi);
  std::vector<std::uint16_t> raw;
  std::vector<float> roi;
  fx.frame(150, 150, 10, 150 - kRoi / 2, 150 - kRoi / 2, 12.0, rng, raw, roi, pf);
  std::uint64_t allocs = 0;
  int used = 0;
  {
    rt::alloc::ScopedArm arm;
    const std::uint64_t before = rt::alloc::this_thread_allocations();
    for (int f = 0; f < 20; ++f) {
      used += obs->observe(0, roi.data(), kRoi, kRoi, raw.data(), kRoi, 8, kRoi / 2.0, kRoi / 2.0, 10.0);
      if (f == 10) obs->discard();
    }
    allocs = rt::alloc::this_thread_allocations() - before;
  }
  EXPECT_EQ(used, 20);
  EXPECT_EQ(allocs, 0u);
  EXPECT_NE(obs->take(), nullptr) << "4-frame batches: one is waiting for the worker";
  // Off the ROI: not used, no crash.
  EXPECT_FALSE(obs->observe(0, roi.data(), kRoi, kRoi, raw.data(), kRoi, 8, 5.0, 5.0, 0.0));
}

TEST(Appearance, ClosedLoopLearnsSwapsBanksWithoutAllocating) {
  // The procedural gripper moving over its textured background at dose 6 (the background under
  // its rim changes every frame): the tracker learns, publishes a bank with a smaller support,
  // and update() stays allocation-free across the swaps. Not with moving jaws: the explained
  // check (tracker.explained_threshold) sends most jaw frames to LOST before a batch is full, so
  // the closed loop does not learn them (README, Known limitations).
  Scenario s;
  s.target = "gripper";
  s.jaws = false;
  s.motion = "smooth";
  s.dose_e = 6.0;
  s.frames = 120;
  config::TrackerConfig tc;
  tc.appearance.enabled = true;
  SimHarness h(s, tc);
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const Tracker::AppearanceStatus a = h.tracker()->appearance_status();
  const RunStats r = h.stats();
  std::printf("gripper dose 6: updates %u accepted, %u rejected, %u deferred; support %.2f; rms %.3f px, false %d\n",
              a.accepted, a.rejected, a.deferred, a.support_fraction, r.rms_px(), r.false_tracking);
  EXPECT_EQ(h.tracker_allocations(), 0u);
  EXPECT_GE(a.accepted, 2u);
  EXPECT_LT(a.support_fraction, 0.95);
  EXPECT_GT(r.tracked_share(), 0.95);
}

TEST(Appearance, ConcurrentWorkerSwapsBanksWhileTracking) {
  // The product's arrangement: a worker thread (start_appearance_worker) folds batches in and
  // publishes banks while this thread runs update() (the harness also calls
  // maintain_appearance() between frames: a second caller must return, not race). 2° steps
  // (half the bank) so that it also runs under ThreadSanitizer (label concurrency).
  Scenario s;
  s.target = "lamella_post";
  s.motion = "smooth";
  s.dose_e = 6.0;
  s.frames = 100;
  config::TrackerConfig tc;
  tc.angle_step_deg = 2;
  tc.appearance.enabled = true;
  tc.appearance.frames_per_update = 8;
  SimHarness h(s, tc);
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.tracker()->start_appearance_worker();
  h.run();
  const Tracker::AppearanceStatus a = h.tracker()->appearance_status();
  const RunStats r = h.stats();
  std::printf("worker thread: %u updates, %u rejected, %u deferred; tracked %.2f\n", a.accepted, a.rejected, a.deferred,
              r.tracked_share());
  EXPECT_GE(a.accepted + a.rejected, 2u) << "batches reached the model";
  EXPECT_EQ(h.tracker_allocations(), 0u);
  EXPECT_GT(r.tracked_share(), 0.9);
}

namespace {

// The prefiltered variance per pixel of white noise of SD `sd` (the 5-tap binomial, one pass);
// its central-difference gradient's is (1 − Σk_i k_(i+2) / Σk_i²) / 2 = (1 − 28/70) / 2 = 0.3 of it.
double prefiltered_var(double sd) {
  const double k[5] = {1 / 16.0, 4 / 16.0, 6 / 16.0, 4 / 16.0, 1 / 16.0};
  double g = 0;
  for (double v : k) g += v * v;
  return sd * sd * g * g;
}

}  // namespace

TEST(AppearanceTemplate, RefinedTemplateNoiseFallsAsPredictedAndDoesNotDrift) {
  // The target covers the whole circle (no background under the rim): the truth is the noise-free
  // recorded pattern. The recorded pattern carries noise of SD 12 (one frame's); the frames
  // carry the same. After 4 batches of 16 frames every pixel is seen ~8 times: the blend's
  // noise variance falls to (1 − w)²·v_rec + w²·v_obs, w = v_rec / (v_rec + v_obs) ≈ 0.9.
  const Fixture fx(40.0, 12.0);
  config::AppearanceConfig cfg;
  cfg.refine_template = true;
  AppearanceModel model = fx.model(cfg);
  model.set_pattern_noise(0, prefiltered_var(12.0), 0.3 * prefiltered_var(12.0));
  auto obs = fx.observer(16);
  const auto batches = fx.observe(*obs, 64, 0.0, 12.0, 21);
  ASSERT_EQ(batches.size(), 4u);
  AppearanceDecision d;
  for (const auto& b : batches) {
    d = model.update(b);
    ASSERT_TRUE(d.accepted) << d.why;
    EXPECT_TRUE(d.template_updated) << d.template_why;
    EXPECT_LT(std::hypot(d.align_dx, d.align_dy), 0.1);
    EXPECT_LT(std::abs(d.align_dphi_deg), 0.15);
  }
  ASSERT_EQ(d.refined.size(), fx.reference.size());
  const double before = fx.error_vs_truth(fx.reference), after = fx.error_vs_truth(d.refined);
  const double predicted = std::sqrt(d.template_noise_factor);
  std::printf("template error vs truth: recorded %.3f, refined %.3f (ratio %.3f, predicted %.3f, weight %.2f)\n", before,
              after, after / before, predicted, d.template_weight);
  EXPECT_LT(after / before, 0.5);
  // The prediction from the two noise variances holds within what interpolation adds (the
  // frames are sampled bilinearly twice: the scene and the observer).
  EXPECT_GT(after / before, 0.8 * predicted);
  EXPECT_LT(after / before, 1.6 * predicted);
}

TEST(AppearanceTemplate, ShiftedAndTurnedBatchesAreCorrectedOrRefused) {
  // A tracker that reports every pose 0.6 px and 0.6° off: the support's drift check lets
  // such batches through (max_drift_px 1), so the template's own alignment must find the offset
  // and take it out — the refined template stays on the recorded pattern's frame (its error
  // against the truth falls as for exact poses; uncorrected, 0.6 px of shift on this texture's
  // gradients is larger than the recorded pattern's noise). 2° off exceeds max_drift_deg: refused,
  // the template unchanged.
  const Fixture fx(40.0, 12.0);
  config::AppearanceConfig cfg;
  cfg.refine_template = true;
  AppearanceModel model = fx.model(cfg);
  model.set_pattern_noise(0, prefiltered_var(12.0), 0.3 * prefiltered_var(12.0));
  auto obs = fx.observer(16);
  const auto batches = fx.observe(*obs, 64, 0.6, 12.0, 22, 0.6);
  ASSERT_EQ(batches.size(), 4u);
  AppearanceDecision d;
  for (const auto& b : batches) {
    d = model.update(b);
    ASSERT_TRUE(d.accepted) << d.why;
    ASSERT_TRUE(d.template_updated) << d.template_why;
    // The observation is the target seen from a pose 0.6 px / 0.6° off: the recorded pattern
    // moved by that much (the field's x offset turns with the target in the pattern's frame).
    // (Measured 0.45-0.50 px and 0.35-0.45 deg per batch: the two offsets are found together,
    // not exactly as told; the check that matters is the template's error below.)
    EXPECT_GT(std::hypot(d.align_dx, d.align_dy), 0.3);
    EXPECT_LT(std::hypot(d.align_dx, d.align_dy), 0.8);
    EXPECT_GT(std::abs(d.align_dphi_deg), 0.25);
    EXPECT_LT(std::abs(d.align_dphi_deg), 0.8);
  }
  const double before = fx.error_vs_truth(fx.reference), after = fx.error_vs_truth(d.refined);
  std::printf("offset poses: template error vs truth recorded %.3f, refined %.3f; alignment (%.3f, %.3f) px %.3f deg\n",
              before, after, d.align_dx, d.align_dy, d.align_dphi_deg);
  EXPECT_LT(after / before, 0.6) << "the corrected template must not carry the pose offset";
  // Refused: 2° off.
  const std::vector<float> kept = d.refined;
  auto obs2 = fx.observer(16);
  const auto turned = fx.observe(*obs2, 16, 0.0, 12.0, 23, 2.0, 64);
  ASSERT_EQ(turned.size(), 1u);
  const AppearanceDecision r = model.update(turned[0]);
  if (r.accepted) {
    EXPECT_FALSE(r.template_updated) << "a 2 deg offset must be refused by max_drift_deg";
    EXPECT_NE(r.template_why.find("deg"), std::string::npos) << r.template_why;
    EXPECT_EQ(r.refined, kept) << "a refused batch must leave the template as it was";
  }
}

TEST(AppearanceTemplate, StandingTargetDoesNotWriteItsBackgroundIntoTheTemplate) {
  // The target of the ring fixture (background under the rim) stands still away from where its
  // pattern was recorded: its batches teach the support but must not enter the template (the
  // rim would become this one patch of background); with the motion gate at 0 they do.
  const Fixture fx(kDiscR, 12.0);
  for (const double gate : {2.0, 0.0}) {
    config::AppearanceConfig cfg;
    cfg.refine_template = true;
    cfg.refine_min_motion_px = gate;
    AppearanceModel model = fx.model(cfg);
    model.set_pattern_noise(0, prefiltered_var(12.0), 0.3 * prefiltered_var(12.0));
    auto obs = fx.observer(16);
    std::mt19937 rng(31);
    Prefilter pf(1, kRoi, kRoi);
    std::vector<std::uint16_t> raw;
    std::vector<float> roi;
    int batches = 0, entered = 0;
    for (int f = 0; f < 48; ++f) {
      fx.frame(250.5, 230.5, 0, 250 - kRoi / 2, 230 - kRoi / 2, 12.0, rng, raw, roi, pf);
      obs->observe(0, roi.data(), kRoi, kRoi, raw.data(), kRoi, 8, kRoi / 2 + 0.5, kRoi / 2 + 0.5, 0.0, 250.5, 230.5);
      if (const AppearanceStats* b = obs->take()) {
        const AppearanceDecision d = model.update(*b);
        obs->give_back();
        ++batches;
        if (d.accepted && d.template_updated) ++entered;
        if (gate > 0) {
          EXPECT_FALSE(d.template_updated) << "motion " << d.motion_px;
        }
      }
    }
    EXPECT_EQ(batches, 3);
    if (gate == 0) {
      EXPECT_GT(entered, 0) << "without the gate the standing batches do enter (the gate is what refuses)";
    }
  }
}

namespace {

struct LoopFigures {
  double rms_px = 0, rms_deg = 0, tracked = 0;
  int false_tracking = 0;
  Tracker::AppearanceStatus a;
};

// The needle over its textured background (the background under the pattern's rim changes as it
// moves), recorded from one frame at 6 e-/px (the pattern's own noise is a frame's), smooth
// motion: learned appearance with and without the refined template.
LoopFigures needle_loop(bool refine) {
  Scenario s;
  s.target = "needle_tip";
  s.motion = "smooth";
  s.dose_e = 6.0;
  s.frames = 150;
  s.pattern_frames = 1;
  config::TrackerConfig tc;
  tc.appearance.enabled = true;
  tc.appearance.refine_template = refine;
  SimHarness h(s, tc);
  EXPECT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const RunStats r = h.stats();
  LoopFigures f;
  f.rms_px = r.rms_px();
  f.rms_deg = r.rms_deg();
  f.tracked = r.tracked_share();
  f.false_tracking = r.false_tracking;
  f.a = h.tracker()->appearance_status();
  EXPECT_EQ(h.tracker_allocations(), 0u);
  return f;
}

}  // namespace

// The closed loop with the refined template on: it must not make the needle worse (the
// template-update problem: a template that drifts drags every later pose with it). It does not
// make it better either — the target this feature was built for, not met. Measured (2026-12-02
// 15:40 UTC, SEMPOSE_APPEARANCE_TRACE=1): off 0.444 px 0.522 deg, on 0.452 px 0.475 deg; only
// 1 of 9 batches entered the template — the batch's mean observation aligns to the recorded
// pattern at 0.3-1.1 px and 1.5-2.9 deg (beyond max_drift_px / max_drift_deg, refused): over the
// learned support the background mixed into the outline pulls the alignment as it pulls a
// least-squares fit of the pattern (README, Known limitations).
TEST(AppearanceTemplate, ClosedLoopRefinedTemplateDoesNotDrift) {
  const LoopFigures off = needle_loop(false), on = needle_loop(true);
  std::printf("needle, 1-frame pattern, dose 6: refine off %.3f px %.3f deg (tracked %.3f); on %.3f px %.3f deg (tracked "
              "%.3f, %u template updates, weight %.2f)\n",
              off.rms_px, off.rms_deg, off.tracked, on.rms_px, on.rms_deg, on.tracked, on.a.template_updates,
              on.a.template_weight);
  EXPECT_EQ(on.false_tracking, 0);
  EXPECT_GE(on.tracked, off.tracked - 0.02);
  EXPECT_LT(on.rms_px, 1.1 * off.rms_px) << "the refined template made the position worse";
  EXPECT_LT(on.rms_deg, 1.1 * off.rms_deg) << "the refined template made the angle worse";
}

TEST(AppearanceTemplate, AlignFindsAKnownWarp) {
  // The alignment alone: the recorded pattern itself warped by a known shift and turn (the bank's
  // bicubic) is found to 0.02 px / 0.02°.
  const Fixture fx(40.0, 0.0);
  config::AppearanceConfig cfg;
  AppearanceModel model = fx.model(cfg);
  const double c = (kP - 1) / 2.0, dx = 0.45, dy = -0.3, dphi = 0.7;
  const double th = dphi * M_PI / 180.0;
  std::vector<double> obs(fx.reference.size()), w(fx.reference.size(), 0.0);
  for (int y = 0; y < kP; ++y)
    for (int x = 0; x < kP; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * kP + x;
      const double u = x - c, v = y - c;
      const double sx = c + std::cos(th) * u - std::sin(th) * v + dx, sy = c + std::sin(th) * u + std::cos(th) * v + dy;
      obs[i] = 2.0 * Scene::bilinear(std::vector<double>(fx.truth.begin(), fx.truth.end()), kP, kP, sx, sy) + 5.0;
      w[i] = fx.circle.inside(x, y) ? 1.0 : 0.0;
    }
  double p[3], gain = 0, offset = 0;
  ASSERT_TRUE(model.align(obs, w, 0, p, gain, offset));
  std::printf("align: %.4f %.4f px %.4f deg gain %.3f offset %.3f\n", p[0], p[1], p[2], gain, offset);
  EXPECT_NEAR(p[0], dx, 0.03);
  EXPECT_NEAR(p[1], dy, 0.03);
  EXPECT_NEAR(p[2], dphi, 0.03);
}
