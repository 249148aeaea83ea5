// The σ stage (pose_uncertainty.hpp) on a synthetic scene whose truth is known: a smooth
// analytic texture rendered exactly at a pose, white Gaussian noise, the walk's measurement.
// σ must match the scatter of the walk's poses where the noise is all there is, grow where the
// residual is structured (clutter the pattern does not have), count the walk's own offset from
// the least-squares optimum, and allocate nothing.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/orientation_walk.hpp"
#include "sempose/pose/pose_uncertainty.hpp"
#include "sempose/pose/roi_loader.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "analytic_scene.hpp"

using namespace sempose;
using namespace sempose::pose;

namespace {

constexpr int kPattern = 48;
constexpr int kRoi = 80;
constexpr double kStepDeg = 1.0;

const test::AnalyticTexture kTexture{40, 16};  // smoother than the walk tests' target

// The target at (cx, cy) turned by phi_deg, plus `clutter` × a smooth blob that is not in the
// pattern (static background under the target's rim), plus white noise of SD noise_sd.
std::vector<std::uint16_t> render(double cx, double cy, double phi_deg, double clutter, double noise_sd, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, noise_sd);
  return test::render_analytic(kRoi, kRoi, cx, cy, phi_deg, kTexture, [&](int x, int y, double v) {
    v += clutter * std::exp(-((x - 50.0) * (x - 50.0) + (y - 30.0) * (y - 30.0)) / 120.0);
    return noise_sd > 0 ? v + noise(rng) : v;
  });
}

struct Stages {
  config::TrackerConfig cfg;
  EngineSizes sizes;
  AngleGrid angles{360, kStepDeg};
  PatternMask fine{kPattern, true, 8, 2}, half_mask{kPattern / 2, true, 8, 1}, coarse_mask{kPattern / 4, true};
  std::unique_ptr<FftCorrelator> half, coarse;
  std::unique_ptr<ExactScorer> scorer;
  std::unique_ptr<RoiLoader> loader;
  SubpixelFit fit{true, true};
  std::unique_ptr<OrientationWalk> walk;
  std::unique_ptr<const PatternBank> bank;
  std::unique_ptr<PoseUncertainty> sigma;

  Stages() {
    cfg.pattern_size_px = kPattern;
    cfg.roi_size_px = kRoi;
    cfg.angle_step_deg = kStepDeg;
    cfg.prefilter_passes = 0;
    cfg.search_downsample = 4;
    sizes = EngineSizes::of(cfg, kPattern, 160, 128);
    half = std::make_unique<FftCorrelator>(sizes.half_fft_px, sizes.half_fft_px, half_mask);
    coarse = std::make_unique<FftCorrelator>(good_fft_size(sizes.coarse_max_w), good_fft_size(sizes.coarse_max_h), coarse_mask);
    scorer = std::make_unique<ExactScorer>(fine, sizes.roi_fft_px);
    loader = std::make_unique<RoiLoader>(0, sizes.roi_fft_px, *scorer, *half);
    maps.assign(static_cast<std::size_t>(sizes.half_fft_px) * sizes.half_fft_px, 0.0f);
    walk = std::make_unique<OrientationWalk>(*scorer, fit, angles);
    bank = make_bank(0.0, 0);
    sigma = std::make_unique<PoseUncertainty>(*scorer, kPattern, PoseUncertainty::kDefaultTilePx, 1.0);
  }

  // The pattern as recorded: the texture plus white noise of SD pattern_noise_sd (seed: which
  // draw of it; 0 SD: the exact texture).
  std::unique_ptr<const PatternBank> make_bank(double pattern_noise_sd, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, pattern_noise_sd);
    PatternBankSpec spec;
    const std::vector<std::uint16_t> pattern = test::render_analytic(
        kPattern, kPattern, (kPattern - 1) / 2.0, (kPattern - 1) / 2.0, 0, kTexture,
        [&](int, int, double v) { return pattern_noise_sd > 0 ? v + noise(rng) : v; });
    spec.pattern = {kPattern, kPattern, pattern};
    spec.angle_step_deg = kStepDeg;
    spec.coarse_step_deg = 20;
    spec.coarse_factor = 4;
    std::string why;
    auto b = PatternBank::build(spec, {fine, half_mask, *half, coarse_mask, *coarse}, why);
    EXPECT_NE(b, nullptr) << why;
    return b;
  }

  // The walk's measurement of the loaded ROI, started at the true angle's grid point.
  Measurement measure(double phi_deg) { return measure(phi_deg, *bank); }
  Measurement measure(double phi_deg, const PatternBank& b) {
    const int j = angles.index_of(phi_deg);
    half->correlate(b.spectrum(j), maps.data());
    const Peak pk = find_peak(maps.data(), half->valid_w(), half->valid_h());
    return walk->measure(b, j, pk, 8);
  }
  std::vector<float> maps;  // the half-resolution correlation map (half_fft_px²)
};

struct Scatter {
  double err2_x = 0, err2_y = 0, err2_phi = 0, sig2_x = 0, sig2_y = 0, sig2_phi = 0;
  int n = 0;
  double ratio_x() const { return std::sqrt(err2_x / sig2_x); }
  double ratio_y() const { return std::sqrt(err2_y / sig2_y); }
  double ratio_phi() const { return std::sqrt(err2_phi / sig2_phi); }
  double sigma_x() const { return std::sqrt(sig2_x / n); }
};

// frames noisy frames of the target at a fixed sub-pixel pose: the walk's error against the σ
// the stage reports (RMS of each), added to s. bank / sigma: st's unless given; seed: the frames' noise.
Scatter run(Stages& st, double clutter, double noise_sd, int frames, Scatter s = {}, const PatternBank* bank = nullptr,
            PoseUncertainty* sigma = nullptr, unsigned seed = 7) {
  std::mt19937 rng(seed);
  const double cx = 40.3, cy = 39.6, phi = 12.4;
  const PatternBank& b = bank ? *bank : *st.bank;
  PoseUncertainty& stage = sigma ? *sigma : *st.sigma;
  for (int f = 0; f < frames; ++f) {
    const auto roi = render(cx, cy, phi, clutter, noise_sd, rng);
    EXPECT_TRUE(st.loader->load(roi.data(), kRoi, kRoi, kRoi, 16));
    const Measurement m = st.measure(phi, b);
    if (!m.valid) continue;
    const PoseSigma sg = stage.estimate(b, m, 1.0);
    EXPECT_TRUE(sg.valid);
    if (!sg.valid) continue;
    const double ex = m.ux + m.dx + (kPattern - 1) / 2.0 - cx, ey = m.uy + m.dy + (kPattern - 1) / 2.0 - cy;
    const double ephi = (m.j + m.dj) * kStepDeg - phi;
    s.err2_x += ex * ex;
    s.err2_y += ey * ey;
    s.err2_phi += ephi * ephi;
    s.sig2_x += sg.x_px * sg.x_px;
    s.sig2_y += sg.y_px * sg.y_px;
    s.sig2_phi += sg.phi_deg * sg.phi_deg;
    ++s.n;
  }
  return s;
}

}  // namespace

TEST(PoseUncertainty, SigmaMatchesTheWalksScatterUnderWhiteNoise) {
  Stages st;
  const Scatter s = run(st, 0.0, 60.0, 200);
  ASSERT_GT(s.n, 190);
  std::printf("white noise: RMS(error)/RMS(sigma) x %.2f y %.2f phi %.2f, sigma_x %.3f px\n", s.ratio_x(), s.ratio_y(),
              s.ratio_phi(), s.sigma_x());
  EXPECT_GT(s.ratio_x(), 0.75);
  EXPECT_LT(s.ratio_x(), 1.3);
  EXPECT_GT(s.ratio_y(), 0.75);
  EXPECT_LT(s.ratio_y(), 1.3);
  EXPECT_GT(s.ratio_phi(), 0.75);
  EXPECT_LT(s.ratio_phi(), 1.3);
}

TEST(PoseUncertainty, StructuredResidualRaisesSigmaWithTheError) {
  Stages st;
  const Scatter white = run(st, 0.0, 60.0, 60);
  const Scatter clutter = run(st, 150.0, 60.0, 60);
  std::printf("sigma_x white %.3f px, with clutter %.3f px; RMS(error)/RMS(sigma) with clutter x %.2f y %.2f phi %.2f\n",
              white.sigma_x(), clutter.sigma_x(), clutter.ratio_x(), clutter.ratio_y(), clutter.ratio_phi());
  EXPECT_GT(clutter.sigma_x(), 1.5 * white.sigma_x());
  // The clutter's pull is a bias no single frame separates from the pose, but σ must not be
  // blind to it: within a factor 2 of the error it causes.
  EXPECT_LT(clutter.ratio_x(), 2.0);
  EXPECT_LT(clutter.ratio_y(), 2.0);
}

TEST(PoseUncertainty, CountsTheWalksOffsetFromTheOptimum) {
  Stages st;
  std::mt19937 rng(3);
  const auto roi = render(40.3, 39.6, 12.4, 0.0, 5.0, rng);
  ASSERT_TRUE(st.loader->load(roi.data(), kRoi, kRoi, kRoi, 16));
  Measurement m = st.measure(12.4);
  ASSERT_TRUE(m.valid);
  const PoseSigma at = st.sigma->estimate(*st.bank, m, 1.0);
  m.dx += 0.4;  // a walk that stopped 0.4 px off
  const PoseSigma off = st.sigma->estimate(*st.bank, m, 1.0);
  ASSERT_TRUE(at.valid && off.valid);
  EXPECT_LT(at.x_px, 0.1);
  EXPECT_GT(off.x_px, 0.3);
}

TEST(PoseUncertainty, InvalidOutsideTheRoiAndNoAllocation) {
  Stages st;
  std::mt19937 rng(5);
  const auto roi = render(40.3, 39.6, 12.4, 0.0, 30.0, rng);
  ASSERT_TRUE(st.loader->load(roi.data(), kRoi, kRoi, kRoi, 16));
  const Measurement m = st.measure(12.4);
  ASSERT_TRUE(m.valid);
  Measurement outside = m;
  outside.ux = kRoi - kPattern + 1;
  EXPECT_FALSE(st.sigma->estimate(*st.bank, outside, 1.0).valid);
  std::uint64_t allocs = 0;
  PoseSigma s;
  {
    rt::alloc::ScopedArm arm;
    const std::uint64_t before = rt::alloc::this_thread_allocations();
    for (int i = 0; i < 50; ++i) s = st.sigma->estimate(*st.bank, m, 1.0 + 0.001 * i);
    allocs = rt::alloc::this_thread_allocations() - before;
  }
  EXPECT_EQ(allocs, 0u);
  EXPECT_TRUE(s.valid);
  // The per-angle JᵀJ cache (as the tracker builds the stage) changes nothing: first call
  // (computes and keeps it), second call (reads it), a stage without the cache.
  PoseUncertainty cached(*st.scorer, kPattern, PoseUncertainty::kDefaultTilePx, 1.0, 0, 0, 0, 1, st.angles.count);
  const PoseSigma first = cached.estimate(*st.bank, m, 1.0), again = cached.estimate(*st.bank, m, 1.0);
  const PoseSigma plain = st.sigma->estimate(*st.bank, m, 1.0);
  EXPECT_EQ(first.x_px, plain.x_px);
  EXPECT_EQ(again.x_px, plain.x_px);
  EXPECT_EQ(again.phi_deg, plain.phi_deg);
  EXPECT_EQ(again.scale, plain.scale);
  EXPECT_TRUE(std::isfinite(s.x_px) && std::isfinite(s.phi_deg) && std::isfinite(s.scale));
}

// The recorded pattern's own noise (PatternBank::noise_gram): the bank reads the pattern's
// noise; with a pattern recorded noisily (SD 40, the frames' 120: the benchmark's 10-frame
// average at any dose has a third of a frame's noise SD) σ grows and stays calibrated — over
// many recordings of the pattern, since one recording's noise is the same error in every
// frame. The white-noise part is what the pattern's noise changes (the sandwich keeps H0), so
// the stage here is that part alone. Without the noise taken out of JᵀJ this σ is too small
// (RMS(error)/RMS(σ) y 1.43, φ 1.64) and smaller than with the clean pattern.
TEST(PoseUncertainty, PatternNoiseIsMeasuredAtSetup) {
  Stages st;
  ASSERT_NE(st.bank, nullptr);
  std::printf("clean pattern's noise read: %.2f\n", std::sqrt(st.bank->pattern_noise_var()));
  EXPECT_LT(st.bank->pattern_noise_var(), 9.0);  // the exact texture: its rounding and curvature only
  const auto noisy = st.make_bank(80.0, 11);
  ASSERT_NE(noisy, nullptr);
  std::printf("pattern noise read: %.1f (true 80.0), rho %.2f\n", std::sqrt(noisy->pattern_noise_var()), noisy->pattern_noise_rho());
  EXPECT_NEAR(std::sqrt(noisy->pattern_noise_var()), 80.0, 8.0);
  ASSERT_NE(noisy->noise_gram(0), nullptr);
  ASSERT_NE(noisy->noise_gram(359), nullptr);
  // Its x and y gradient energy alike (white noise), φ's and the gain's above 0.
  const double* g = noisy->noise_gram(37);
  EXPECT_NEAR(g[0] / g[7], 1.0, 0.15);
  EXPECT_GT(g[14], 0.0);
  EXPECT_GT(g[28], 0.0);
}

TEST(PoseUncertainty, NoisierPatternGivesLargerSigmaAndStaysCalibrated) {
  Stages st;
  constexpr double kFrameSd = 120, kPatternSd = 40;
  PoseUncertainty fisher(*st.scorer, kPattern, PoseUncertainty::kDefaultTilePx, 0.0, 0, 0, 1.0, 1, st.angles.count, true);
  const Scatter clean = run(st, 0.0, kFrameSd, 40, {}, st.bank.get(), &fisher);
  Scatter noisy;
  constexpr int kRecordings = 40, kFrames = 5;
  for (int r = 0; r < kRecordings; ++r) {
    const auto bank = st.make_bank(kPatternSd, 100 + r);
    ASSERT_NE(bank, nullptr);
    noisy = run(st, 0.0, kFrameSd, kFrames, noisy, bank.get(), &fisher, 200 + r);
  }
  ASSERT_GT(noisy.n, kRecordings * kFrames * 9 / 10);
  const auto sd = [](const Scatter& s, double v) { return std::sqrt(v / s.n); };
  std::printf("clean pattern: sigma x %.4f y %.4f phi %.4f; RMS(error)/RMS(sigma) x %.2f y %.2f phi %.2f\n",
              sd(clean, clean.sig2_x), sd(clean, clean.sig2_y), sd(clean, clean.sig2_phi), clean.ratio_x(), clean.ratio_y(),
              clean.ratio_phi());
  std::printf("noisy pattern: sigma x %.4f y %.4f phi %.4f; RMS(error)/RMS(sigma) x %.2f y %.2f phi %.2f\n",
              sd(noisy, noisy.sig2_x), sd(noisy, noisy.sig2_y), sd(noisy, noisy.sig2_phi), noisy.ratio_x(), noisy.ratio_y(),
              noisy.ratio_phi());
  EXPECT_GT(sd(noisy, noisy.sig2_x), 1.1 * sd(clean, clean.sig2_x));
  EXPECT_GT(sd(noisy, noisy.sig2_y), 1.2 * sd(clean, clean.sig2_y));
  EXPECT_GT(sd(noisy, noisy.sig2_phi), sd(clean, clean.sig2_phi));
  EXPECT_GT(noisy.ratio_x(), 0.75);
  EXPECT_LT(noisy.ratio_x(), 1.3);
  EXPECT_GT(noisy.ratio_y(), 0.75);
  EXPECT_LT(noisy.ratio_y(), 1.3);
  EXPECT_GT(noisy.ratio_phi(), 0.75);
  EXPECT_LT(noisy.ratio_phi(), 1.3);
}

// The frame's sharpness against the copy (PoseSigma::sharpness, README: Uncertainty,
// *Sharpness*): ~1 on a frame that is the pattern plus noise, lower on the same frame blurred by
// a Gaussian PSF (the fit's curvature falls by that ratio); its noise SD small against the fall.
TEST(PoseUncertainty, SharpnessFallsOnABlurredFrame) {
  Stages st;
  std::mt19937 rng(9);
  auto blurred = [](const std::vector<std::uint16_t>& in, double psf_px) {
    const int r = static_cast<int>(std::ceil(3 * psf_px));
    std::vector<double> k(2 * r + 1);
    double sum = 0;
    for (int i = -r; i <= r; ++i) sum += k[i + r] = std::exp(-0.5 * i * i / (psf_px * psf_px));
    for (double& v : k) v /= sum;
    std::vector<double> tmp(in.size());
    std::vector<std::uint16_t> out(in.size());
    for (int y = 0; y < kRoi; ++y)
      for (int x = 0; x < kRoi; ++x) {
        double v = 0;
        for (int i = -r; i <= r; ++i) v += k[i + r] * in[static_cast<std::size_t>(y) * kRoi + std::clamp(x + i, 0, kRoi - 1)];
        tmp[static_cast<std::size_t>(y) * kRoi + x] = v;
      }
    for (int y = 0; y < kRoi; ++y)
      for (int x = 0; x < kRoi; ++x) {
        double v = 0;
        for (int i = -r; i <= r; ++i) v += k[i + r] * tmp[static_cast<std::size_t>(std::clamp(y + i, 0, kRoi - 1)) * kRoi + x];
        out[static_cast<std::size_t>(y) * kRoi + x] = static_cast<std::uint16_t>(std::lround(v));
      }
    return out;
  };
  const auto sharp = render(40.3, 39.6, 12.4, 0.0, 0.0, rng);
  double last = 2.0;
  for (const double psf : {0.0, 3.0, 6.0}) {
    auto roi = psf > 0 ? blurred(sharp, psf) : sharp;
    std::normal_distribution<double> noise(0.0, 30.0);
    for (auto& v : roi) v = static_cast<std::uint16_t>(std::lround(std::clamp(v + noise(rng), 0.0, 65535.0)));
    ASSERT_TRUE(st.loader->load(roi.data(), kRoi, kRoi, kRoi, 16));
    const Measurement m = st.measure(12.4);
    ASSERT_TRUE(m.valid);
    const PoseSigma s = st.sigma->estimate(*st.bank, m, 1.0);
    ASSERT_TRUE(s.valid);
    std::printf("PSF %.1f px: sharpness %.3f (noise SD %.3f), sigma_x %.3f px\n", psf, s.sharpness, s.sharpness_sd, s.x_px);
    if (psf == 0) {
      EXPECT_NEAR(s.sharpness, 1.0, 0.15) << "the frame is the pattern plus noise";
    }
    EXPECT_LT(s.sharpness, last - 3 * s.sharpness_sd) << "blurrier: lower by more than its noise";
    EXPECT_GT(s.sharpness_sd, 0.0);
    last = s.sharpness;
  }
  EXPECT_LT(last, 0.6) << "a 6 px PSF (the texture is smooth: 0.87 at 3 px)";
}
