// Detector statistics against dose (README: The simulated SEM): mean = λ, variance = λ(1 + 1/k) + σ_read²
// for Poisson electrons through a Gamma(k) gain cascade; SNR grows as √dwell.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sempose/hal/sim_source.hpp"
#include "test_util.hpp"

namespace sempose::hal {
namespace {

struct Stats {
  double mean_e = 0, var_e = 0;
};

// Flat grey scene of brightness b; returns detected-electron statistics of one full frame.
Stats measure(double b, std::uint32_t dwell_ns, double read_noise_e, std::uint64_t seed = 3) {
  ScanLimits lim;
  lim.field_w = lim.field_h = 256;
  lim.max_roi_w = lim.max_roi_h = 256;
  lim.bits = 16;
  config::SimConfig c = test::clean_config();
  c.noise = true;
  c.seed = seed;
  c.background.mean = b;
  c.read_noise_e = read_noise_e;
  c.output_white = 0.08;   // far from saturation even for rare large counts
  c.output_offset = 0.3;   // room below for read noise
  SimSource src(lim, c);
  std::vector<Pixel> px(256 * 256);
  TargetTruth truth[kMaxTargets];
  src.render({0, 0, 256, 256}, dwell_ns, SimSource::kVirtualEpochNs, 0, px.data(), truth);
  const double n_white = c.electrons_per_pixel(dwell_ns);
  const double cpe = c.output_white * 65535 / n_white, off = c.output_offset * 65535;
  double s = 0, s2 = 0;
  for (Pixel p : px) {
    const double e = (p - off) / cpe;
    s += e, s2 += e * e;
  }
  Stats st;
  st.mean_e = s / px.size();
  st.var_e = s2 / px.size() - st.mean_e * st.mean_e;
  return st;
}

TEST(SimNoise, MeanAndVarianceFollowTheDetectorCascade) {
  const config::SimConfig defaults;
  const double k = defaults.detector_gain_shape;
  for (std::uint32_t dwell : {250u, 1000u, 4000u}) {
    for (double read : {0.0, 0.5}) {
      const double lambda = 0.5 * defaults.electrons_per_pixel(dwell);
      const Stats st = measure(0.5, dwell, read);
      EXPECT_NEAR(st.mean_e, lambda, 0.02 * lambda) << "dwell " << dwell;
      const double var = lambda * (1 + 1 / k) + read * read;
      EXPECT_NEAR(st.var_e, var, 0.05 * var) << "dwell " << dwell << " read " << read;
    }
  }
}

// A long dwell at a high beam current (in range: 100 nA, yield 10, 0.1 s a pixel) asks for ~6e10
// electrons a pixel, more than 32 bits hold: the count's cast to an integer was undefined there
// and the frame came out black (mean 11 of 255 grey levels where 1 ms gave 69). The mean
// electron count must still be the dose's.
TEST(SimNoise, DoseBeyondThirtyTwoBitsOfElectronsKeepsItsMean) {
  ScanLimits lim;
  lim.field_w = lim.field_h = 64;
  lim.max_roi_w = lim.max_roi_h = 64;
  lim.max_dwell_ns = 100'000'000;
  config::SimConfig c = test::clean_config();
  c.noise = true;
  c.background.mean = 0.5;
  c.beam_current_pa = 100000;
  c.yield = 10;
  const std::uint32_t dwell = 100'000'000;
  const double n_white = c.electrons_per_pixel(dwell);
  ASSERT_GT(0.5 * n_white, 4.3e9) << "the case needs more electrons than 32 bits hold";
  SimSource src(lim, c);
  std::vector<Pixel> px(64 * 64);
  TargetTruth truth[kMaxTargets];
  src.render({0, 0, 64, 64}, dwell, SimSource::kVirtualEpochNs, 0, px.data(), truth);
  const double cpe = c.output_white * 255 / n_white, off = c.output_offset * 255;
  double s = 0;
  for (Pixel p : px) s += (p - off) / cpe;
  EXPECT_NEAR(s / px.size(), 0.5 * n_white, 0.02 * 0.5 * n_white);
}

TEST(SimNoise, DefaultDoseGivesSingleDigitElectronsAt250ns) {
  const config::SimConfig c;
  const double n = c.electrons_per_pixel(250);
  EXPECT_GT(n, 1.0);
  EXPECT_LT(n, 10.0);
}

TEST(SimNoise, SnrGrowsWithTheSquareRootOfDwell) {
  auto snr = [](std::uint32_t dwell) {
    const Stats st = measure(0.5, dwell, 0.3);
    return st.mean_e / std::sqrt(st.var_e);
  };
  const double s250 = snr(250), s1000 = snr(1000), s4000 = snr(4000);
  EXPECT_NEAR(s1000 / s250, 2.0, 0.12);
  EXPECT_NEAR(s4000 / s1000, 2.0, 0.12);
  // At 250 ns a pixel is very noisy (SNR of a few), as in the paper's images.
  EXPECT_LT(s250, 3.0);
}

TEST(SimNoise, SameSeedSameFrameOtherSeedOtherFrame) {
  const Stats a = measure(0.4, 250, 0.3, 11), b = measure(0.4, 250, 0.3, 11), c = measure(0.4, 250, 0.3, 12);
  EXPECT_EQ(a.mean_e, b.mean_e);
  EXPECT_EQ(a.var_e, b.var_e);
  EXPECT_NE(a.mean_e, c.mean_e);
}

}  // namespace
}  // namespace sempose::hal
