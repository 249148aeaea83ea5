// The attainable score (attainable_score.hpp) against the score a perfectly aligned pattern
// actually reaches: frames of a known scene with the detector's noise (Poisson electrons ×
// Gamma gain + read noise) put through the detector's first-order low-pass along each line
// (τ = 0, 0.5, 1, 2 px), at 20, 6, 2.5 and 1 e⁻/px. The reached score is the ZNCC, over the
// same p×p window, of the prefiltered frame and the prefiltered noise-free frame (what the
// detector would deliver without shot noise: the pattern a long average records). Its mean
// over trials is what the estimate must predict. The white-noise model (Immerkær × Σk², the
// estimator before the line's correlation was read) is printed beside it: on low-passed noise
// it promises too much wherever the noise is not negligible (14 of the 24 checked rows break
// the bounds below; substituted for the product's estimator, this test fails).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "sempose/hal/pgm.hpp"
#include "sempose/pose/attainable_score.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/window_noise.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace sempose::pose {
namespace {

constexpr int kFrame = 160;    // frame side; the window sits in its middle (the prefilter's edges stay outside)
constexpr int kPattern = 128;  // window side: the default pattern
constexpr int kBits = 16;      // no clipping or quantisation to speak of: the test is about the noise model
constexpr int kPasses = 1;     // the default prefilter

// A brightness map in [0, 1] (kFrame²): a real SEM crop, or the procedural scene.
std::vector<double> scene(const std::string& name) {
  std::vector<double> b(static_cast<std::size_t>(kFrame) * kFrame);
  if (name == "procedural") {
    // A bar with a bevelled rim and soft blobs on a dim background: edges in every direction
    // and smooth interior detail, as the simulator's procedural lamella.
    for (int y = 0; y < kFrame; ++y)
      for (int x = 0; x < kFrame; ++x) {
        const double u = (x - 80.0) * std::cos(0.4) + (y - 80.0) * std::sin(0.4);
        const double v = -(x - 80.0) * std::sin(0.4) + (y - 80.0) * std::cos(0.4);
        const double inside = 1.0 / (1.0 + std::exp((std::max(std::fabs(u) - 50.0, std::fabs(v) - 30.0)) / 0.8));
        double blobs = 0;
        for (int k = 0; k < 6; ++k) {
          const double bx = 55.0 + 11.0 * k, by = 70.0 + 5.0 * (k % 3);
          blobs += std::exp(-((x - bx) * (x - bx) + (y - by) * (y - by)) / (2 * 16.0));
        }
        b[static_cast<std::size_t>(y) * kFrame + x] = 0.2 + 0.5 * inside + 0.25 * inside * blobs;
      }
    return b;
  }
  const bool needle = name == "needle_tip";
  const hal::Image img =
      hal::read_pgm(std::string(SEMPOSE_TEST_DATA) + (needle ? "/sem/needle_contact_eb.pgm" : "/sem/lamella_on_post_eb.pgm"));
  const int x0 = needle ? 520 : 430, y0 = needle ? 420 : 470;  // the benchmark's targets
  const double maxv = img.bits == 8 ? 255.0 : 65535.0;
  for (int y = 0; y < kFrame; ++y)
    for (int x = 0; x < kFrame; ++x) b[static_cast<std::size_t>(y) * kFrame + x] = img.at(x0 + x, y0 + y) / maxv;
  return b;
}

// The detector: counts for brightness b at `dose` electrons per pixel for brightness 1, each
// line low-passed as the simulator does (y += a·(x − y), a = 1 − exp(−1/τ_px); settled on the
// line's first pixel). noise = false: the expected counts (the pattern's view).
void detect(const std::vector<double>& b, double dose, double tau_px, bool noise, std::mt19937_64& rng,
            std::vector<double>& out) {
  out.assign(b.size(), 0.0);
  const double a = tau_px > 0 ? 1.0 - std::exp(-1.0 / tau_px) : 1.0;
  constexpr double kShape = 3.0, kReadE = 0.3;  // the simulator's defaults
  // Brightness 1 → 2000 counts above an offset of 4000 whatever the dose: even at 1 e⁻/px no
  // electron count or negative read noise reaches 0 or full scale (clipping would hide noise).
  const double counts_per_e = 2000.0 / dose;
  std::normal_distribution<double> read(0.0, kReadE);
  for (int y = 0; y < kFrame; ++y) {
    double lp = 0;
    for (int x = 0; x < kFrame; ++x) {
      const double mean_e = b[static_cast<std::size_t>(y) * kFrame + x] * dose;
      double e = mean_e;
      if (noise) {
        const int n = std::poisson_distribution<int>(mean_e)(rng);
        e = n > 0 ? std::gamma_distribution<double>(n * kShape, 1.0 / kShape)(rng) : 0.0;
        e += read(rng);
      }
      lp = x == 0 ? e : lp + a * (e - lp);
      out[static_cast<std::size_t>(y) * kFrame + x] = 4000.0 + lp * counts_per_e;
    }
  }
}

// ZNCC of two equally sized windows.
double zncc(const std::vector<double>& f, const std::vector<double>& t) {
  double mf = 0, mt = 0;
  for (std::size_t i = 0; i < f.size(); ++i) mf += f[i], mt += t[i];
  mf /= static_cast<double>(f.size());
  mt /= static_cast<double>(t.size());
  double ft = 0, ff = 0, tt = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    ft += (f[i] - mf) * (t[i] - mt);
    ff += (f[i] - mf) * (f[i] - mf);
    tt += (t[i] - mt) * (t[i] - mt);
  }
  return ft / std::sqrt(ff * tt);
}

// The product's prefilter on a frame of counts, the middle kPattern² window out.
std::vector<double> filtered_window(const std::vector<std::uint16_t>& frame) {
  Prefilter pf(kPasses, kFrame, kFrame);
  std::vector<std::int32_t> out(frame.size());
  pf.apply(frame.data(), kFrame, kFrame, kFrame, kBits, out.data());
  std::vector<double> w(static_cast<std::size_t>(kPattern) * kPattern);
  const int o = (kFrame - kPattern) / 2;
  for (int y = 0; y < kPattern; ++y)
    for (int x = 0; x < kPattern; ++x) w[static_cast<std::size_t>(y) * kPattern + x] = out[static_cast<std::size_t>(y + o) * kFrame + x + o];
  return w;
}

std::vector<std::uint16_t> to_counts(const std::vector<double>& v) {
  std::vector<std::uint16_t> c(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) c[i] = static_cast<std::uint16_t>(std::clamp(std::lround(v[i]), 0L, 65535L));
  return c;
}

struct Row {
  double reached = 0, estimated = 0, white_model = 0, rho = 0;
};

Row measure(const std::vector<double>& b, double dose, double tau_px, int trials, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> mean_counts;
  detect(b, dose, tau_px, false, rng, mean_counts);
  const std::vector<double> pattern = filtered_window(to_counts(mean_counts));
  const PrefilterNoiseGain gain(kPasses);
  const double c = (kFrame - 1) / 2.0;  // the window's centre: the middle kPattern² (as filtered_window)
  const int x0 = (kFrame - kPattern) / 2;
  Row r;
  std::vector<double> noisy;
  for (int t = 0; t < trials; ++t) {
    detect(b, dose, tau_px, true, rng, noisy);
    const std::vector<std::uint16_t> frame = to_counts(noisy);
    r.reached += zncc(filtered_window(frame), pattern);
    const AttainableScore a = attainable_score(frame.data(), kFrame, kFrame, c, c, kPattern, gain);
    r.estimated += a.score;
    r.rho += a.noise.rho;
    const double white = std::min(a.window_var, window_noise_var(frame.data(), kFrame, x0, x0, kPattern));
    const double s = a.window_var - white;
    r.white_model += std::sqrt(s / (s + gain.white() * white));
  }
  r.reached /= trials;
  r.estimated /= trials;
  r.white_model /= trials;
  r.rho /= trials;
  return r;
}

// What the line's correlation must not change: on low-passed noise the estimate is off the
// reached score by no more than on white noise at the same dose (+0.03, the run-to-run spread of
// 12 trials), and never below it by more than 0.04. On white noise the estimate is Immerkær's
// (window_noise.hpp): within 0.03 at >= 6 e-/px; at 2.5 and 1 e-/px his mean-absolute estimator
// reads too little of the skewed Poisson × Gamma noise (+0.04–0.05 and +0.12–0.16 here), a known
// bias the decision thresholds were measured with, printed rather than hidden.
constexpr double kTolOverWhite = 0.03, kTolUnder = 0.04, kTolHighDose = 0.03;

// Scenes whose raw signal-to-noise variance ratio stays above ~0.07 at 1 e-/px: the procedural
// lamella and the needle tip at the benchmark's scale. The lamella on its post at native
// resolution is printed only: its texture is the micrograph's own frozen pixel noise, so at
// 2.5 e-/px S/N ≈ 0.03 and S = var − N is not measurable from one frame (README: Known limitations).
TEST(AttainableScore, MatchesTheReachedScoreUnderLineLowPassAndWhiteNoise) {
  int failures_white_model = 0, low_passed_rows = 0;
  std::printf("%-12s %5s %5s | %7s %7s %7s | %6s %6s\n", "scene", "tau", "dose", "reached", "est", "white", "rho",
              "true");
  for (const char* name : {"procedural", "needle_tip", "lamella_post"}) {
    const bool checked = std::string(name) != "lamella_post";
    const std::vector<double> b = scene(name);
    for (double dose : {20.0, 6.0, 2.5, 1.0}) {
      double white_bias = 0;  // est − reached on white noise at this dose
      for (double tau : {0.0, 0.5, 1.0, 2.0}) {
        const Row r = measure(b, dose, tau, 12, 1000 + static_cast<std::uint64_t>(dose * 10 + tau * 1000));
        const double true_rho = tau > 0 ? std::exp(-1.0 / tau) : 0.0;
        std::printf("%-12s %5.1f %5.1f | %7.3f %7.3f %7.3f | %6.3f %6.3f%s\n", name, tau, dose, r.reached, r.estimated,
                    r.white_model, r.rho, true_rho, checked ? "" : "  (printed only)");
        const double bias = r.estimated - r.reached;
        if (tau == 0.0) white_bias = bias;
        if (!checked) continue;
        if (dose >= 6.0) {
          EXPECT_NEAR(r.estimated, r.reached, kTolHighDose) << name << " tau " << tau << " dose " << dose;
        }
        EXPECT_GE(bias, -kTolUnder) << name << " tau " << tau << " dose " << dose;
        if (tau > 0) {
          EXPECT_LE(bias, std::max(0.0, white_bias) + kTolOverWhite) << name << " tau " << tau << " dose " << dose;
          ++low_passed_rows;
          failures_white_model += r.white_model - r.reached > std::max(0.0, white_bias) + kTolOverWhite ||
                                  (dose >= 6.0 && std::fabs(r.white_model - r.reached) > kTolHighDose);
        }
      }
    }
  }
  std::printf("the white-noise model (Immerkær × Σk²) breaks these bounds on %d of %d checked low-passed rows\n",
              failures_white_model, low_passed_rows);
}

// A pattern with noise of its own (a crop of one frame, or an average of few): the score a
// perfectly aligned noisy pattern reaches on a noisy frame is the product of each copy's
// √(S/(S+N')), so the frame's attainable score × the pattern's factor (pattern_attainable_factor,
// from the noise line_correlated_noise reads on the raw pattern, as PatternBank measures it)
// must match it. The pattern: one detection of the procedural scene at 20, 6 and 2.5 e-/px
// (τ 0.5 px); the frames: 12 detections at 6 e-/px. Without the factor the estimate promises
// more than the pattern can reach once its own noise counts (measured: +0.023, +0.055, +0.113;
// with it +0.010, +0.018, +0.039, the last Immerkær's bias at 2.5 e-/px).
TEST(AttainableScore, PatternNoiseFactorMatchesNoisyPatternOnNoisyFrame) {
  const std::vector<double> b = scene("procedural");
  const PrefilterNoiseGain gain(kPasses);
  const double c = (kFrame - 1) / 2.0;
  const int o = (kFrame - kPattern) / 2;
  std::printf("%10s | %7s %7s %7s %7s\n", "pattern e", "factor", "reached", "est", "est*f");
  for (double pattern_dose : {20.0, 6.0, 2.5}) {
    std::mt19937_64 rng(4242 + static_cast<std::uint64_t>(pattern_dose * 10));
    std::vector<double> counts;
    detect(b, pattern_dose, 0.5, true, rng, counts);
    const std::vector<std::uint16_t> pattern_frame = to_counts(counts);
    const std::vector<double> pattern = filtered_window(pattern_frame);
    std::vector<std::uint16_t> raw(static_cast<std::size_t>(kPattern) * kPattern);  // the pattern as recorded
    for (int y = 0; y < kPattern; ++y)
      for (int x = 0; x < kPattern; ++x)
        raw[static_cast<std::size_t>(y) * kPattern + x] = pattern_frame[static_cast<std::size_t>(y + o) * kFrame + x + o];
    const double factor =
        pattern_attainable_factor(raw.data(), kPattern, line_correlated_noise(raw.data(), kPattern, 0, 0, kPattern), gain);
    double reached = 0, est = 0;
    constexpr int kTrials = 12;
    std::vector<double> noisy;
    for (int t = 0; t < kTrials; ++t) {
      detect(b, 6.0, 0.5, true, rng, noisy);
      const std::vector<std::uint16_t> frame = to_counts(noisy);
      reached += zncc(filtered_window(frame), pattern);
      est += attainable_score(frame.data(), kFrame, kFrame, c, c, kPattern, gain).score;
    }
    reached /= kTrials;
    est /= kTrials;
    std::printf("%10.1f | %7.3f %7.3f %7.3f %7.3f\n", pattern_dose, factor, reached, est, est * factor);
    EXPECT_LE(factor, 1.0);
    if (pattern_dose >= 6.0) {
      EXPECT_NEAR(est * factor, reached, kTolHighDose) << "pattern at " << pattern_dose << " e-/px";
    } else {
      // Immerkær's mean-absolute estimator reads too little of the skewed noise at 2.5 e-/px
      // (+0.04-0.05 on a frame, above): on the pattern too, so the product keeps part of it.
      EXPECT_GE(est * factor - reached, -kTolUnder) << "pattern at " << pattern_dose << " e-/px";
      EXPECT_LE(est * factor - reached, 0.05) << "pattern at " << pattern_dose << " e-/px";
      EXPECT_GT(est - reached, 0.1) << "the noise-free pattern's promise must miss here, or this case shows nothing";
    }
    EXPECT_LT(std::fabs(est * factor - reached), 0.5 * (est - reached)) << "the factor takes out most of the gap";
  }
  // A flat pattern or no noise read: factor 1 (nothing to take out), finite.
  const std::vector<std::uint16_t> flat(static_cast<std::size_t>(kPattern) * kPattern, 1000);
  EXPECT_EQ(pattern_attainable_factor(flat.data(), kPattern, WindowNoise{}, gain), 1.0);
}

// The line's correlation itself: ρ read from the window is the detector's exp(−1/τ).
TEST(AttainableScore, ReadsTheLineCorrelation) {
  const std::vector<double> b = scene("lamella_post");
  for (double tau : {0.0, 0.5, 1.0, 2.0}) {
    const Row r = measure(b, 6.0, tau, 6, 77);
    const double true_rho = tau > 0 ? std::exp(-1.0 / tau) : 0.0;
    EXPECT_NEAR(r.rho, true_rho, 0.06) << "tau " << tau;
  }
}

// RT: no heap call, and a flat or too small window scores 0 without NaN.
TEST(AttainableScore, AllocationFreeAndFiniteOnDegenerateWindows) {
  std::vector<std::uint16_t> flat(static_cast<std::size_t>(kFrame) * kFrame, 500);
  const PrefilterNoiseGain gain(kPasses);
  AttainableScore a, small;
  std::uint64_t allocs = 0;
  {
    rt::alloc::ScopedArm arm;
    const std::uint64_t before = rt::alloc::this_thread_allocations();
    a = attainable_score(flat.data(), kFrame, kFrame, 80, 80, kPattern, gain);
    small = attainable_score(flat.data(), 64, 64, 32, 32, kPattern, gain);
    allocs = rt::alloc::this_thread_allocations() - before;
  }
  EXPECT_EQ(allocs, 0u);
  EXPECT_EQ(a.score, 0.0);
  EXPECT_EQ(small.score, 0.0);
  flat[5000] = 900;  // one hot pixel: all noise, no signal
  EXPECT_TRUE(std::isfinite(attainable_score(flat.data(), kFrame, kFrame, 80, 80, kPattern, gain).score));
}

// The prefilter's gain: white noise keeps Σk² (70/256 per axis for one pass); correlated noise
// keeps what a direct filtering of AR(1) noise keeps.
TEST(AttainableScore, PrefilterGainOnCorrelatedNoiseMatchesFilteredNoise) {
  const PrefilterNoiseGain gain(1);
  EXPECT_NEAR(gain.white(), (70.0 / 256) * (70.0 / 256), 1e-12);
  EXPECT_NEAR(gain.line_correlated(0.0), gain.white(), 1e-12);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01;
  for (double rho : {0.3, 0.6}) {
    // AR(1) rows of unit variance, independent across rows, through the 1-D kernel twice (x, y).
    const int w = 400, h = 400;
    std::vector<double> v(static_cast<std::size_t>(w) * h);
    for (int y = 0; y < h; ++y) {
      double p = n01(rng);
      for (int x = 0; x < w; ++x) {
        p = x == 0 ? p : rho * p + std::sqrt(1 - rho * rho) * n01(rng);
        v[static_cast<std::size_t>(y) * w + x] = p;
      }
    }
    static constexpr double k[5] = {1 / 16.0, 4 / 16.0, 6 / 16.0, 4 / 16.0, 1 / 16.0};
    double s2 = 0;
    int cnt = 0;
    for (int y = 2; y + 2 < h; ++y)
      for (int x = 2; x + 2 < w; ++x) {
        double f = 0;
        for (int i = 0; i < 5; ++i)
          for (int j = 0; j < 5; ++j) f += k[i] * k[j] * v[static_cast<std::size_t>(y + i - 2) * w + x + j - 2];
        s2 += f * f;
        ++cnt;
      }
    EXPECT_NEAR(s2 / cnt, gain.line_correlated(rho), 0.04 * gain.line_correlated(rho)) << "rho " << rho;
  }
}

}  // namespace
}  // namespace sempose::pose
