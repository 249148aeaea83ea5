// The detector's line correlation measured from frames (line_correlation.hpp): synthetic frames
// of known ρ = e^(−1/τ_px) — Poisson electrons per pixel, then a first-order low-pass along each
// line as the simulator's detector applies it — on a flat scene and on a real micrograph's
// structure, at 20 / 6 / 2.5 / 1 e⁻/px.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "sempose/hal/pgm.hpp"
#include "sempose/pose/detector_lag.hpp"
#include "sempose/pose/line_correlation.hpp"

namespace sempose::pose {
namespace {

constexpr int kSide = 192;  // a tracking ROI

// One frame: brightness b(x, y) in [0, 1] at `dose` electrons for brightness 1, low-passed along
// each line with ρ (settled on the line's first pixel), 16-bit counts (1000 per electron / dose).
template <class Brightness>
std::vector<std::uint16_t> frame(Brightness b, double dose, double rho, std::mt19937_64& rng) {
  std::vector<std::uint16_t> px(static_cast<std::size_t>(kSide) * kSide);
  for (int y = 0; y < kSide; ++y) {
    double lp = 0;
    for (int x = 0; x < kSide; ++x) {
      const double mean = b(x, y) * (dose > 0 ? dose : 1.0);
      std::poisson_distribution<int> electrons(std::max(1e-9, mean));
      const double e = dose > 0 ? electrons(rng) : mean;  // dose ≤ 0: the noise-free structure
      lp = x == 0 ? e : lp + (1.0 - rho) * (e - lp);
      px[static_cast<std::size_t>(y) * kSide + x] = static_cast<std::uint16_t>(std::lround(std::min(65535.0, lp * 1000.0 / (dose > 0 ? dose : 1.0))));
    }
  }
  return px;
}

hal::Image micrograph() {
  hal::Image im;
  std::string error;
  const bool ok = hal::try_read_pgm(std::string(SEMPOSE_TEST_DATA) + "/sem/lamella_on_post_eb.pgm", im, error);
  EXPECT_TRUE(ok) << error;
  return im;
}

// Over 8 frames (the crops moved about the micrograph's lamella and post), the estimate's ρ
// within tol of the truth, and its lag within tol / (1 − ρ)² of the true lag.
TEST(LineCorrelation, RecoversRhoOnFlatAndRealStructureAtEveryDose) {
  const hal::Image im = micrograph();
  ASSERT_GT(im.width, 700);
  const double maxv = im.bits > 8 ? 65535.0 : 255.0;
  for (int scene = 0; scene < 2; ++scene) {
    for (double tau_px : {0.0, 1.0, 2.0, 4.0}) {
      const double rho = tau_px > 0 ? std::exp(-1.0 / tau_px) : 0.0;
      for (double dose : {20.0, 6.0, 2.5, 1.0}) {
        std::mt19937_64 rng(static_cast<std::uint64_t>(1000 * tau_px + dose));
        DetectorTauEstimator est;
        for (int f = 0; f < 8; ++f) {
          const int ox = 300 + 37 * f, oy = 350 + 53 * f;
          auto b = [&](int x, int y) {
            return scene == 0 ? 0.5 : im.pixels[static_cast<std::size_t>(oy + y) * im.width + ox + x] / maxv;
          };
          const std::vector<std::uint16_t> px = frame(b, dose, rho, rng);
          est.read(line_correlation_sums(px.data(), kSide, kSide, kSide, line_correlation_row_step(kSide, kSide)), 250);
          est.keep();
        }
        // The micrograph's own structure (and its own noise) reads ≤ 0.013 at 20 e-/px.
        const double tol = scene == 1 && dose >= 20 ? 0.02 : 0.01;
        const char* name = scene == 0 ? "flat" : "micrograph";
        EXPECT_NEAR(est.rho_at(250), rho, tol) << name << " τ " << tau_px << " px, " << dose << " e-/px";
        const double lag = tau_px > 0 ? DetectorLag::px(250 * tau_px, 250) : 0.0;
        EXPECT_NEAR(est.lag_px(250), lag, tol / ((1 - rho) * (1 - rho)) + 1e-9) << name << " τ " << tau_px << " px, " << dose;
        if (tau_px > 0) {
          EXPECT_NEAR(est.tau_ns(), 250 * tau_px, 0.1 * 250 * tau_px) << name << " " << dose;
        }
      }
    }
  }
}

// What correlates the line differences along the lines without being a detector's low-pass
// (the lag-2 check, LineCorrelationSums): every 4th line dropped to the black level (its
// neighbour's scene, smooth along x, left in z: ρ1 0.12–0.74 read, ρ2 ≈ ρ1), flat and
// micrograph scenes, 20 to 1 e⁻/px, 8 frames: no lag, no τ. Main (0f5fdd5) read them as a
// detector's lag of 0.14–3.04 px. A real low-pass: the test above.
TEST(LineCorrelation, DroppedLinesAreNoDetectorLag) {
  const hal::Image im = micrograph();
  ASSERT_GT(im.width, 700);
  const double maxv = im.bits > 8 ? 65535.0 : 255.0;
  const int step = line_correlation_row_step(kSide, kSide);
  for (int scene = 0; scene < 2; ++scene)
    for (double dose : {20.0, 6.0, 2.5, 1.0}) {
      std::mt19937_64 rng(static_cast<std::uint64_t>(10 * dose + scene));
      DetectorTauEstimator est;
      LineCorrelationSums last;
      for (int f = 0; f < 8; ++f) {
        const int ox = 300 + 37 * f, oy = 350 + 53 * f;
        auto b = [&](int x, int y) { return scene == 0 ? 0.5 : im.pixels[static_cast<std::size_t>(oy + y) * im.width + ox + x] / maxv; };
        std::vector<std::uint16_t> px = frame(b, dose, 0.0, rng);
        for (int y = f % 4; y < kSide; y += 4)  // the black level: brightness 0.04
          std::fill(px.begin() + y * kSide, px.begin() + (y + 1) * kSide, static_cast<std::uint16_t>(40));
        last = line_correlation_sums(px.data(), kSide, kSide, kSide, step);
        est.read(last, 250);
        est.keep();
      }
      char what_c[96];
      std::snprintf(what_c, sizeof what_c, "every 4th line dropped, %s, %.1f e-/px", scene == 0 ? "flat" : "micrograph", dose);
      const std::string what = what_c;
      std::printf("%s: line rho %.3f (last frame), lag %.2f px\n", what_c, last.rho(), est.lag_px(250));
      EXPECT_TRUE(last.noise_dominates(DetectorTauEstimator::kMinNoiseShare)) << what << ": the gate lets it through";
      EXPECT_GT(last.rho(), 0.1) << what << ": it correlates the lines' differences";
      EXPECT_EQ(est.lag_px(250), 0.0) << what;
      EXPECT_EQ(est.tau_ns(), 0.0) << what;
    }
}

// Sums of a given ρ whose noise dominates (the gate open: noise_share() 1), a first-order
// low-pass's (ρ2 = ρ²).
LineCorrelationSums noisy_sums(double rho) {
  LineCorrelationSums s;
  s.along = rho;
  s.along2 = rho * rho;
  s.power = 1.0;
  s.pairs = DetectorTauEstimator::kPairBudget;
  s.second_abs = static_cast<double>(s.pairs) * std::sqrt(6.0 * s.power / (M_PI * static_cast<double>(s.pairs)));
  s.power *= 1e6, s.along *= 1e6, s.along2 *= 1e6, s.second_abs *= 1e3;  // noise of ~7 grey levels: above the floor
  return s;
}

// A frame's reading counts for its own lag at once and joins the estimate only when kept; below
// kFastRho the detector is fast (no lag).
TEST(LineCorrelation, EstimatorKeepsOnlyKeptFrames) {
  LineCorrelationSums s = noisy_sums(0.6);
  EXPECT_NEAR(s.noise_share(), 1.0, 1e-12);
  DetectorTauEstimator est;
  EXPECT_EQ(est.lag_px(100), 0.0);
  est.read(s, 100);
  EXPECT_NEAR(est.rho_at(100), 0.6, 1e-12);
  EXPECT_NEAR(est.lag_px(100), 1.5, 1e-12);
  EXPECT_NEAR(est.tau_ns(), -100 / std::log(0.6), 1e-9);
  est.keep();
  LineCorrelationSums torn = s;
  torn.along = 0.0;  // a frame whose pose was not accepted: read, not kept
  est.read(torn, 100);
  EXPECT_NEAR(est.rho_at(100), 0.3, 1e-12);
  est.read(s, 100);  // replaces the unkept reading
  EXPECT_NEAR(est.rho_at(100), 0.6, 1e-12);
  EXPECT_FALSE(est.settled());
  s = noisy_sums(0.04);
  DetectorTauEstimator fast;
  fast.read(s, 100);
  EXPECT_EQ(fast.lag_px(100), 0.0);
  EXPECT_EQ(fast.tau_ns(), 0.0);
  // Nothing to read (blank, saturated or tiny frames) changes nothing.
  const std::vector<std::uint16_t> blank(64 * 64, 0);
  EXPECT_FALSE(line_correlation_sums(blank.data(), 64, 64, 64, 2).valid());
  EXPECT_FALSE(line_correlation_sums(blank.data(), 4, 64, 64, 2).valid());
  EXPECT_FALSE(line_correlation_sums(nullptr, 64, 64, 64, 2).valid());
}

// ρ = e^(−d/τ) moves with the dwell, so frames at 100 and 200 ns read ρ and ρ²: the estimate
// learns that the dwell explains the readings and maps ρ to each frame's dwell. A replay reports
// the governor's dwell while its frames were all recorded at one: the readings stay put whatever
// dwell is reported, and the estimate keeps ρ as read (mapping it would put the lag 2.5x off).
TEST(LineCorrelation, DwellMappingOnlyWhereTheReadingsFollowTheDwell) {
  auto reading = [](double rho) { return noisy_sums(rho); };
  DetectorTauEstimator hardware, replay;
  for (int f = 0; f < 20; ++f) {
    const double dwell = f % 2 ? 200 : 100;
    hardware.read(reading(f % 2 ? 0.36 : 0.6), dwell);
    hardware.keep();
    replay.read(reading(0.6), dwell);
    replay.keep();
  }
  EXPECT_TRUE(hardware.follows_dwell());
  EXPECT_NEAR(hardware.rho_at(100), 0.6, 1e-9);
  EXPECT_NEAR(hardware.rho_at(200), 0.36, 1e-9);
  EXPECT_NEAR(hardware.tau_ns(), -100 / std::log(0.6), 1e-6);
  EXPECT_FALSE(replay.follows_dwell());
  EXPECT_NEAR(replay.rho_at(100), 0.6, 1e-9);
  EXPECT_NEAR(replay.rho_at(200), 0.6, 1e-9);
}

// The gate (noise_share): a scene of sharp structure — a disk, a bar along the lines, one
// across them, a gradient; edges 1 px wide as a PSF leaves them — under white Poisson noise of
// known ρ reads ρ with the gate open at 1–20 e⁻/px, every band as the tracker reads them; the
// same scene without noise (what a noise-free synthetic frame is) closes it: read raw, its
// horizontal bar alone reads ρ ≈ 1 (z is constant along that edge): a detector of τ 0 reads 0.17.
// Its flat bands hold only the 16-bit levels' rounding, below the noise floor kMinNoiseVar.
TEST(LineCorrelation, GateOpensOnNoiseAndClosesOnNoiseFreeStructure) {
  auto edge = [](double d) { return 0.5 * (1.0 + std::tanh(d)); };
  auto scene = [&](int x, int y) {
    const double r = std::hypot(x - 80.0, y - 90.0);
    return 0.2 + 0.0015 * x + 0.4 * edge(40.0 - r) + 0.25 * edge(y - 140.0) * edge(170.0 - y) + 0.2 * edge(x - 150.0) * edge(165.0 - x);
  };
  const int step = line_correlation_row_step(kSide, kSide), band = line_correlation_band_pairs(kSide);
  for (double tau_px : {0.0, 1.0, 2.0, 4.0}) {
    const double rho = tau_px > 0 ? std::exp(-1.0 / tau_px) : 0.0;
    for (double dose : {20.0, 6.0, 2.5, 1.0, 0.0}) {
      std::mt19937_64 rng(static_cast<std::uint64_t>(100 * tau_px + dose));
      const std::vector<std::uint16_t> px = frame(scene, dose, rho, rng);
      const std::string what = "τ " + std::to_string(tau_px) + " px, dose " + std::to_string(dose);
      const LineCorrelationSums whole = line_correlation_sums(px.data(), kSide, kSide, kSide, step);
      DetectorTauEstimator est;
      int open_bands = 0, bands = 0;
      for (int line = 0; line + 2 < kSide; line += band * step, ++bands) {
        const LineCorrelationSums s = line_correlation_sums(px.data(), kSide, kSide, kSide, step, line, band);
        open_bands += s.noise_dominates(DetectorTauEstimator::kMinNoiseShare);
        est.read(s, 250);
        est.keep();
      }
      if (dose > 0) {
        EXPECT_GE(whole.noise_share(), 0.75) << what;
        EXPECT_EQ(open_bands, bands) << what;
        EXPECT_NEAR(est.rho_at(250), rho, 0.02) << what;
        EXPECT_NEAR(pattern_line_rho(px.data(), kSide, kSide), rho >= DetectorTauEstimator::kLagFreeRho ? rho : 0.0, 0.03) << what;
      } else {
        EXPECT_LT(whole.noise_share(), 0.3) << what;
        if (tau_px == 0) {
          EXPECT_GT(whole.rho(), 0.1) << what << ": the scene's leak this gate is for";
        }
        EXPECT_EQ(open_bands, 0) << what;
        EXPECT_FALSE(est.has_reading()) << what;
        EXPECT_EQ(est.lag_px(250), 0.0) << what;
        EXPECT_EQ(pattern_line_rho(px.data(), kSide, kSide), 0.0) << what;
      }
    }
  }
}

// A pattern is read in tiles (pattern_line_rho): averaged from 10 frames it has a tenth of a
// frame's noise against the same structure, and read whole the structure's edges leak into ρ.
// The scene above at 200 e⁻/px (10 frames of 20): lag-free reads 0, through the detector its ρ.
TEST(LineCorrelation, PatternIsReadInTheTilesWhereItsNoiseDominates) {
  auto edge = [](double d) { return 0.5 * (1.0 + std::tanh(d)); };
  auto scene = [&](int x, int y) {
    const double r = std::hypot(x - 64.0, y - 64.0);
    return 0.2 + 0.6 * edge(40.0 - r) + 0.3 * edge(y - 100.0) * edge(112.0 - y);
  };
  for (double tau_px : {0.0, 2.0}) {
    const double rho = tau_px > 0 ? std::exp(-1.0 / tau_px) : 0.0;
    std::mt19937_64 rng(17);
    const std::vector<std::uint16_t> px = frame(scene, 200.0, rho, rng);
    const LineCorrelationSums whole = line_correlation_sums(px.data(), kSide, kSide, kSide, 1);
    const double tiles = pattern_line_rho(px.data(), kSide, kSide);
    std::printf("τ %.0f px, 200 e-/px: read whole ρ %.3f (gate share %.2f), in tiles %.3f\n", tau_px, whole.rho(),
                whole.noise_share(), tiles);
    EXPECT_NEAR(tiles, rho, 0.03) << "τ " << tau_px;
  }
}

// A told τ is overruled only where the readings differ by more than their own error in ρ and
// the lags by more than the measured correction's own: the simulator's τ 120 ns at 250 ns (ρ
// 0.125, lag 0.14 px) against a pattern reading rounded to lag-free agrees; a pattern told at
// the frames' dwell of τ 4 px (ρ 0.78) but reading 0.01 does not, nor frames told τ 1 px (0.37)
// reading 0.77. A noise-free pattern opens no tile: no reading, which is not "lag-free".
TEST(LineCorrelation, ToldLagIsOverruledOnlyBeyondTheReadingsError) {
  EXPECT_FALSE(DetectorTauEstimator::told_disagrees(std::exp(-250.0 / 120.0), 0.0));
  EXPECT_FALSE(DetectorTauEstimator::told_disagrees(std::exp(-1.0), 0.33));
  EXPECT_FALSE(DetectorTauEstimator::told_disagrees(std::exp(-0.25), 0.748));  // τ 4 px read as 3.45
  EXPECT_TRUE(DetectorTauEstimator::told_disagrees(std::exp(-0.25), 0.01));
  EXPECT_TRUE(DetectorTauEstimator::told_disagrees(std::exp(-1.0), 0.77));
  EXPECT_TRUE(DetectorTauEstimator::told_disagrees(0.0, 0.6));  // told lag-free, recorded through the detector
  const std::vector<std::uint16_t> flat(static_cast<std::size_t>(kSide) * kSide, 1000);
  const PatternLineRho none = read_pattern_line_rho(flat.data(), kSide, kSide);
  EXPECT_FALSE(none.readable());
  EXPECT_EQ(none.lag_rho(), 0.0);
}

}  // namespace
}  // namespace sempose::pose

