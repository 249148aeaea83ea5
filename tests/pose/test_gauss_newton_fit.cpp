// The final Gauss–Newton fit (gauss_newton_fit.hpp) on a synthetic scene whose pose is known: a
// smooth analytic texture rendered exactly (no interpolation) at sub-pixel, sub-step poses, loaded
// and prefiltered as the tracker loads it, the bank built as the tracker builds it.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/angle_sweep.hpp"
#include "sempose/pose/gauss_newton_fit.hpp"
#include "sempose/pose/orientation_walk.hpp"
#include "sempose/pose/peak_finder.hpp"
#include "sempose/pose/pose_refinement.hpp"
#include "sempose/pose/roi_loader.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "analytic_scene.hpp"

using namespace sempose;
using namespace sempose::pose;

namespace {

constexpr int kPattern = 48;
constexpr int kRoi = 80;
constexpr double kStepDeg = 1.0;
constexpr double kC = (kPattern - 1) / 2.0;

// The bank, scorer and loader for a 48 px pattern, 80 px ROI, 1° steps, one prefilter pass.
struct Stages {
  config::TrackerConfig cfg;
  EngineSizes sizes;
  PatternMask fine{kPattern, true, 16, 4}, half_mask{kPattern / 2, true, 8, 2}, coarse_mask{kPattern / 4, true};
  std::unique_ptr<FftCorrelator> half, coarse;
  std::unique_ptr<ExactScorer> scorer;
  std::unique_ptr<RoiLoader> loader;
  std::unique_ptr<const PatternBank> bank;

  // pattern: the recorded pattern (kPattern², 16-bit levels); empty: the analytic texture rendered exactly.
  explicit Stages(std::vector<std::uint16_t> pattern = {}) {
    cfg.pattern_size_px = kPattern;
    cfg.roi_size_px = kRoi;
    cfg.angle_step_deg = kStepDeg;
    cfg.prefilter_passes = 1;
    cfg.search_downsample = 4;
    sizes = EngineSizes::of(cfg, kPattern, 160, 160);
    half = std::make_unique<FftCorrelator>(sizes.half_fft_px, sizes.half_fft_px, half_mask);
    coarse = std::make_unique<FftCorrelator>(good_fft_size(sizes.coarse_max_w), good_fft_size(sizes.coarse_max_h), coarse_mask);
    scorer = std::make_unique<ExactScorer>(fine, sizes.roi_fft_px);
    loader = std::make_unique<RoiLoader>(1, sizes.roi_fft_px, *scorer, *half);
    PatternBankSpec spec;
    if (pattern.empty()) pattern = test::render_analytic(kPattern, kPattern, kC, kC, 0);
    spec.pattern = {kPattern, kPattern, pattern};
    spec.prefilter_passes = 1;
    spec.angle_step_deg = kStepDeg;
    spec.coarse_step_deg = cfg.search_angle_step_deg;
    spec.coarse_factor = cfg.search_downsample;
    std::string why;
    bank = PatternBank::build(spec, {fine, half_mask, *half, coarse_mask, *coarse}, why);
    EXPECT_NE(bank, nullptr) << why;
  }
  bool load(const std::vector<std::uint16_t>& roi) { return loader->load(roi.data(), kRoi, kRoi, kRoi, 16); }
  // The template the seam builds (prefiltered source): the bank's angle-0 copy over its support.
  FitTemplate tpl() const {
    std::vector<std::uint8_t> inside(static_cast<std::size_t>(kPattern) * kPattern, 0);
    for (int k = 0; k < bank->support_band_count(0); ++k) {
      const MaskBand& b = bank->support_bands(0)[k];
      for (int y = b.y0; y <= b.y1; ++y)
        for (int x = b.x0; x <= b.x1; ++x) inside[static_cast<std::size_t>(y) * kPattern + x] = 1;
    }
    FitTemplate t;
    EXPECT_TRUE(t.build(bank->pattern(0), kPattern, inside.data()));
    return t;
  }
  FitResult fit(const GaussNewtonFit& f, const FitTemplate& t, const FitPose& start) const {
    return f.fit(t, scorer->roi(), scorer->roi_w(), scorer->roi_h(), scorer->roi_w(), start);
  }
};

config::RefineConfig refine_on() {
  config::RefineConfig c;
  c.enabled = true;
  c.max_iterations = 5;
  return c;
}

double angle_error(double a, double b) { return std::fabs(std::fmod(a - b + 540.0, 360.0) - 180.0); }

}  // namespace

// Noise-free: started 0.45 px, 0.4 px and 0.45° off (the walk's worst grid rounding), the fit
// lands on the rendered pose. The template is angle j's bicubic copy and the ROI is sampled
// bilinearly, so not to the last bit; the walk's own quadratic is 0.03 px off at best.
TEST(GaussNewtonFit, NoiseFreeRecoversAKnownWarp) {
  Stages st;
  GaussNewtonFit fit(refine_on());
  const FitTemplate tpl = st.tpl();
  for (const double phi : {0.3, 17.6, -121.4}) {
    const double cx = 40.37, cy = 38.81;
    ASSERT_TRUE(st.load(test::render_analytic(kRoi, kRoi, cx, cy, phi)));
    const FitPose start{cx + 0.45, cy - 0.4, phi + 0.45, 1.0};
    const FitResult r = st.fit(fit, tpl, start);
    ASSERT_EQ(r.status, FitStatus::kRefined) << phi;
    EXPECT_NEAR(r.pose.cx, cx, 0.02) << phi;
    EXPECT_NEAR(r.pose.cy, cy, 0.02) << phi;
    EXPECT_NEAR(r.pose.phi_deg, phi, 0.05) << phi;
    EXPECT_NEAR(r.pose.scale, 1.0, 0.003) << phi;
    EXPECT_GT(r.gain, 0);
    EXPECT_LE(r.iterations, 5);
  }
}

// A target 6 % larger than its pattern: with the scale free the fit finds it (and the position
// stays right); with it pinned it keeps scale 1.
TEST(GaussNewtonFit, FitsTheScaleWhenAsked) {
  Stages st;
  const double cx = 39.6, cy = 40.2, s = 1.06;
  test::AnalyticTexture tex;
  // Render the larger target: sample the texture at offsets / s.
  std::vector<std::uint16_t> big(static_cast<std::size_t>(kRoi) * kRoi);
  for (int y = 0; y < kRoi; ++y)
    for (int x = 0; x < kRoi; ++x) big[static_cast<std::size_t>(y) * kRoi + x] = static_cast<std::uint16_t>(std::lround(tex((x - cx) / s, (y - cy) / s)));
  ASSERT_TRUE(st.load(big));
  GaussNewtonFit fit(refine_on());
  const FitTemplate tpl = st.tpl();
  const FitResult r = st.fit(fit, tpl, {cx + 0.3, cy, 0.0, 1.0});
  ASSERT_EQ(r.status, FitStatus::kRefined);
  EXPECT_NEAR(r.pose.scale, s, 0.01);
  EXPECT_NEAR(r.pose.cx, cx, 0.05);
  config::RefineConfig pinned = refine_on();
  pinned.fit_scale = false;
  GaussNewtonFit fixed(pinned);
  EXPECT_EQ(st.fit(fixed, tpl, {cx + 0.3, cy, 0.0, 1.0}).pose.scale, 1.0);
}

// Started outside the basin (the target is 4 px and 10° away: a look-alike's place) the fit
// must not wander: it keeps the start exactly and says so. A start whose pixels leave the ROI
// is skipped, the start kept.
TEST(GaussNewtonFit, DivergenceKeepsTheStart) {
  Stages st;
  ASSERT_TRUE(st.load(test::render_analytic(kRoi, kRoi, 40, 40, 10.0)));
  GaussNewtonFit fit(refine_on());
  const FitTemplate tpl = st.tpl();
  const FitPose start{44.2, 37.1, 0.0, 1.0};
  const FitResult r = st.fit(fit, tpl, start);
  EXPECT_EQ(r.status, FitStatus::kDiverged);
  EXPECT_EQ(r.pose.cx, start.cx);
  EXPECT_EQ(r.pose.cy, start.cy);
  EXPECT_EQ(r.pose.phi_deg, start.phi_deg);
  const FitPose off{5.0, 40.0, 0.0, 1.0};
  const FitResult o = st.fit(fit, tpl, off);
  EXPECT_EQ(o.status, FitStatus::kSkipped);
  EXPECT_EQ(o.pose.cx, off.cx);
}

// Against the walk's own sub-pixel estimate on the same frames (the seam, PoseRefinement, on
// the measurement it was given; 60 frames at random sub-pixel poses and angles): noise-free the
// fit removes most of the quadratic's model error in angle (measured: walk 0.026°, fit 0.007°;
// it must at least halve it) and is not worse in position (0.0036 vs 0.0028 px); with white noise it must not be worse than the walk by more than the run-to-run spread
// (on white noise both are least-squares matches of the same prefiltered pattern: measured
// 0.056 vs 0.054 px, 0.158° vs 0.166°). No heap call in any refine().
TEST(GaussNewtonFit, BeatsTheWalksModelErrorAndMatchesItUnderNoiseWithoutAllocating) {
  Stages st;
  SubpixelFit sub(true, true);
  AngleGrid angles{360, kStepDeg};
  OrientationWalk walk(*st.scorer, sub, angles);
  CorrelationMaps maps(static_cast<std::size_t>(st.sizes.half_fft_px) * st.sizes.half_fft_px);
  PoseRefinement seam(*st.scorer, refine_on(), kStepDeg);
  ASSERT_TRUE(seam.add_set(*st.bank, {}));
  std::uint64_t allocs = 0;
  for (const double noise_sd : {0.0, 60.0}) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> pos(-0.5, 0.5), ang(-30, 30);
    std::normal_distribution<double> noise(0.0, 1.0);
    double walk_px2 = 0, fit_px2 = 0, walk_deg2 = 0, fit_deg2 = 0;
    int n = 0, refined = 0;
    for (int f = 0; f < 60; ++f) {
      const double cx = 40 + pos(rng), cy = 40 + pos(rng), phi = ang(rng);
      const auto roi = test::render_analytic(kRoi, kRoi, cx, cy, phi, {}, [&](int, int, double v) { return v + noise_sd * noise(rng); });
      ASSERT_TRUE(st.load(roi));
      const int j0 = angles.index_of(phi);
      st.half->correlate(st.bank->spectrum(j0), maps.work());
      const Measurement m = walk.measure(*st.bank, j0, find_peak(maps.work(), st.half->valid_w(), st.half->valid_h()), 8);
      ASSERT_TRUE(m.valid);
      Measurement r;
      {
        rt::alloc::ScopedArm arm;
        const std::uint64_t before = rt::alloc::this_thread_allocations();
        r = seam.refine(0, *st.bank, m, {});
        allocs += rt::alloc::this_thread_allocations() - before;
      }
      refined += r.refine_status == static_cast<std::uint8_t>(FitStatus::kRefined);
      auto err = [&](const Measurement& mm, double& px2, double& deg2) {
        px2 += std::pow(mm.ux + mm.dx + kC - cx, 2) + std::pow(mm.uy + mm.dy + kC - cy, 2);
        deg2 += std::pow(angle_error((mm.j + mm.dj) * kStepDeg, phi), 2);
      };
      err(m, walk_px2, walk_deg2);
      err(r, fit_px2, fit_deg2);
      ++n;
    }
    EXPECT_GE(refined, 58) << noise_sd;
    const double walk_px = std::sqrt(walk_px2 / n), fit_px = std::sqrt(fit_px2 / n);
    const double walk_deg = std::sqrt(walk_deg2 / n), fit_deg = std::sqrt(fit_deg2 / n);
    std::printf("noise %.0f, RMS over %d frames: walk %.4f px %.4f deg, fit %.4f px %.4f deg\n", noise_sd, n, walk_px,
                walk_deg, fit_px, fit_deg);
    if (noise_sd == 0) {
      EXPECT_LT(fit_px, walk_px);
      EXPECT_LT(fit_deg, 0.5 * walk_deg);
    } else {
      EXPECT_LT(fit_px, 1.15 * walk_px);
      EXPECT_LT(fit_deg, 1.15 * walk_deg);
    }
  }
  EXPECT_EQ(allocs, 0u);
}


// The efficient estimator (issue 13 item 1): under Poisson noise the least-squares fit of the raw
// frame weighted by 1 / variance (∝ the signal) against a noise-free template. The template
// here is recorded as the tracker's is: the mean of 10 noisy frames. A scene with a dark ground
// (1 electron) and sharp-edged bright shapes (31–61 electrons), so the variance spans 60×; frames at
// random sub-pixel poses and angles, each fitted from the same start 0.3 px / 0.3° off by the
// seam, on one Poisson frame, four ways: the prefiltered source (the walk's objective), raw
// against the recorded pattern as is (the source before this change), raw with the template
// low-passed on its own side, and that with the detector-noise weights. The weighted raw fit
// with the template filter must beat both the unweighted raw fit and the prefiltered one by
// several standard errors, and the weights must beat the same fit unweighted.
TEST(GaussNewtonFit, WeightedRawFitAgainstAFilteredTemplateBeatsTheUnweightedAndPrefilteredFits) {
  constexpr double kGain = 16.0;  // counts per electron (16-bit levels, black level 0)
  // Sharp-edged shapes (edges blurred by a 0.8 px beam) on a dark ground: a disc, a bar and a dot.
  auto lambda = [](double u, double v) {
    auto inside = [](double d) { return 0.5 * std::erfc(d / (std::sqrt(2.0) * 0.8)); };  // d: signed distance out
    const double disc = std::hypot(u + 7, v - 5) - 8;
    const double bar = std::max(std::fabs(u - 7) - 3.5, std::fabs(v + 1) - 13);
    const double dot = std::hypot(u - 2, v + 13) - 3;
    return 1.0 + 30.0 * inside(disc) + 45.0 * inside(bar) + 60.0 * inside(dot);
  };
  // A P×P or ROI image of the scene at (cx, cy, φ) with `frames` Poisson frames averaged.
  std::mt19937 rng(11);
  auto render = [&](int w, int h, double cx, double cy, double phi, int frames) {
    const double c = std::cos(phi * M_PI / 180), sn = std::sin(phi * M_PI / 180);
    std::vector<std::uint16_t> out(static_cast<std::size_t>(w) * h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double dx = x - cx, dy = y - cy;
        std::poisson_distribution<int> pois(lambda(dx * c - dy * sn, dx * sn + dy * c));
        double sum = 0;
        for (int k = 0; k < frames; ++k) sum += pois(rng);
        out[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint16_t>(std::lround(kGain * sum / frames));
      }
    return out;
  };
  const std::vector<std::uint16_t> recorded = render(kPattern, kPattern, kC, kC, 0.0, 10);
  Stages st(recorded);
  AngleGrid angles{360, kStepDeg};
  struct Variant {
    const char* name;
    const char* source;
    int template_passes;
    bool weights;
  };
  const Variant variants[] = {{"prefiltered", "prefiltered", 0, false},
                              {"raw", "raw", 0, false},
                              {"raw, template filtered", "raw", -1, false},
                              {"raw, template filtered, weighted", "raw", -1, true}};
  constexpr int kVariants = 4;
  std::vector<std::unique_ptr<PoseRefinement>> seams;
  for (const Variant& v : variants) {
    config::RefineConfig c = refine_on();
    c.source = v.source;
    c.template_passes = v.template_passes;
    c.noise_weights = v.weights;
    c.black_level = 0.0;
    seams.push_back(std::make_unique<PoseRefinement>(*st.scorer, c, kStepDeg));
    ASSERT_TRUE(seams.back()->add_set(*st.bank, {kPattern, kPattern, recorded}, 16));
  }
  // template_passes auto on this pattern (10 frames of 1–61 electrons, sharp edges): measured 0.
  std::printf("template passes (auto): %d\n", seams[3]->template_passes(0));
  constexpr int kFrames = 300;
  std::uniform_real_distribution<double> pos(-0.5, 0.5), ang(-20, 20);
  // Per variant and frame: squared position error (px²) and squared angle error (deg²).
  std::vector<double> e_px[kVariants], e_deg[kVariants];
  std::uint64_t allocs = 0;
  for (int f = 0; f < kFrames; ++f) {
    const double cx = 40 + pos(rng), cy = 40 + pos(rng), phi = ang(rng);
    const std::vector<std::uint16_t> roi = render(kRoi, kRoi, cx, cy, phi, 1);
    ASSERT_TRUE(st.load(roi));
    // The start: 0.3 px and 0.3° off, as a walk's grid point and offsets.
    const double sx = cx + 0.3 - kC, sy = cy - 0.3 - kC, sphi = phi + 0.3;
    Measurement m;
    m.valid = true;
    m.score = 0.9f;
    m.ux = static_cast<int>(std::lround(sx));
    m.uy = static_cast<int>(std::lround(sy));
    m.dx = sx - m.ux;
    m.dy = sy - m.uy;
    m.j = angles.index_of(sphi);
    m.dj = std::remainder(sphi - m.j * kStepDeg, 360.0) / kStepDeg;
    for (int k = 0; k < kVariants; ++k) {
      Measurement r;
      {
        rt::alloc::ScopedArm arm;
        const std::uint64_t before = rt::alloc::this_thread_allocations();
        r = seams[static_cast<std::size_t>(k)]->refine(0, *st.bank, m, {roi.data(), kRoi});
        allocs += rt::alloc::this_thread_allocations() - before;
      }
      ASSERT_EQ(r.refine_status, static_cast<std::uint8_t>(FitStatus::kRefined)) << variants[k].name << " frame " << f;
      e_px[k].push_back(std::pow(r.ux + r.dx + kC - cx, 2) + std::pow(r.uy + r.dy + kC - cy, 2));
      e_deg[k].push_back(std::pow(angle_error((r.j + r.dj) * kStepDeg, phi), 2));
    }
  }
  EXPECT_EQ(allocs, 0u);
  // Mean squared error and its standard error per variant; the difference of two variants'
  // MSE and its standard error from the paired per-frame differences.
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return s / static_cast<double>(v.size());
  };
  auto paired = [&](const std::vector<double>& a, const std::vector<double>& b, double& diff, double& se) {
    std::vector<double> d(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) d[i] = a[i] - b[i];
    diff = mean(d);
    double ss = 0;
    for (double x : d) ss += (x - diff) * (x - diff);
    se = std::sqrt(ss / static_cast<double>(d.size() - 1) / static_cast<double>(d.size()));
  };
  for (int k = 0; k < kVariants; ++k)
    std::printf("%-34s RMS over %d frames: %.4f px %.4f deg\n", variants[k].name, kFrames, std::sqrt(mean(e_px[k])),
                std::sqrt(mean(e_deg[k])));
  // Measured (300 frames): prefiltered 0.0422 px 0.180°, raw 0.0393 px 0.155°, weighted 0.0380 px
  // 0.134°. Against the prefiltered fit: better by several standard errors in both; against the
  // same raw fit unweighted: several in angle, not worse in position (1.7 SE better).
  constexpr int kBest = 3;
  for (const int other : {0, 2}) {
    double d_px, se_px, d_deg, se_deg;
    paired(e_px[other], e_px[kBest], d_px, se_px);
    paired(e_deg[other], e_deg[kBest], d_deg, se_deg);
    std::printf("MSE %s minus the weighted filtered fit: %.5f ± %.5f px², %.5f ± %.5f deg²\n", variants[other].name, d_px,
                se_px, d_deg, se_deg);
    if (other == 0) EXPECT_GT(d_px, 3 * se_px) << variants[other].name;
    else EXPECT_GT(d_px, -se_px) << variants[other].name;
    EXPECT_GT(d_deg, 3 * se_deg) << variants[other].name;
  }
}

// template_passes auto: a noise-free recorded pattern is not filtered; the same scene recorded
// from one frame at a few electrons per pixel is (its noise's gradient outweighs the edges').
TEST(GaussNewtonFit, AutoTemplatePassesFollowThePatternsNoise) {
  std::vector<std::uint8_t> inside(static_cast<std::size_t>(kPattern) * kPattern, 0);
  for (int y = 0; y < kPattern; ++y)
    for (int x = 0; x < kPattern; ++x) inside[static_cast<std::size_t>(y) * kPattern + x] = std::hypot(x - kC, y - kC) < 20;
  std::mt19937 rng(5);
  auto pattern = [&](double electrons_per_level) {
    std::vector<std::uint16_t> px = test::render_analytic(kPattern, kPattern, kC, kC, 0);
    for (std::uint16_t& p : px) {
      if (electrons_per_level <= 0) continue;
      std::poisson_distribution<int> pois(p * electrons_per_level);
      p = static_cast<std::uint16_t>(std::lround(pois(rng) / electrons_per_level));
    }
    return PatternImage{kPattern, kPattern, px};
  };
  const int clean = PoseRefinement::auto_template_passes(pattern(0), inside);
  const int noisy = PoseRefinement::auto_template_passes(pattern(0.002), inside);  // 2–4 electrons per pixel
  std::printf("auto template passes: noise-free %d, 2-4 e-/px %d\n", clean, noisy);
  EXPECT_EQ(clean, 0);
  EXPECT_GE(noisy, 1);
}
