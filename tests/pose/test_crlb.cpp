// The Cramér–Rao bound helper (crlb.hpp) against what must hold whatever the scene: the
// 1/√dose law, no bound for a scene without structure (or with only the static background),
// the analytic Fisher information of a quadratic scene, and the detector's excess noise.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "crlb.hpp"

using namespace sempose;
using namespace sempose::pose;
using namespace sempose::pose::testing;

namespace {

const WarpScene& lamella() {
  static const WarpScene s = WarpScene::load(std::string(SEMPOSE_TEST_DATA) + "/sem/lamella_on_post_eb.pgm", 1.0);
  return s;
}

// A synthetic scene of w×h pixels holding f(X, Y) at its pixel centres.
template <class F>
WarpScene synthetic(int w, int h, F f) {
  WarpScene s;
  s.w = w;
  s.h = h;
  s.sigma = 1.0;
  s.v.resize(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) s.v[static_cast<std::size_t>(y) * w + x] = static_cast<float>(f(x, y));
  return s;
}

}  // namespace

TEST(Crlb, RealSemLamellaAtDose6IsFiniteAndPrinted) {
  const config::TrackerConfig tc;
  const Crlb c = crlb_warp(lamella(), 563.5, 527.5, tc, 190.3, 160.7, 0.0, 6.0);
  ASSERT_TRUE(c.valid);
  std::printf("lamella_on_post crop, dose 6, φ 0: sd_x %.3f sd_y %.3f px, 2-D %.3f px, φ %.3f° over %d px\n", c.sd_x_px(),
              c.sd_y_px(), c.pos_rms_px(), c.phi_deg(), c.pixels);
  // The mask is the tracker's circle (radius P/2 − 4 at one prefilter pass).
  // (Its rows are grouped in bands that take their narrowest row's width: a little under πr².)
  EXPECT_LE(c.pixels, M_PI * 60.0 * 60.0);
  EXPECT_GE(c.pixels, 0.85 * M_PI * 60.0 * 60.0);
  // Covariance is positive definite: correlations within (−1, 1).
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b) EXPECT_LT(std::fabs(c.cov[a][b]) / std::sqrt(c.cov[a][a] * c.cov[b][b]), 1.0);
  EXPECT_TRUE(std::isfinite(c.pos_rms_px()));
  EXPECT_GT(c.pos_rms_px(), 0.0);
}

TEST(Crlb, PoissonBoundScalesAsOneOverSqrtDose) {
  const config::TrackerConfig tc;
  for (double phi : {0.0, 37.0}) {
    const Crlb a = crlb_warp(lamella(), 563.5, 527.5, tc, 190.3, 160.7, phi, 6.0);
    const Crlb b = crlb_warp(lamella(), 563.5, 527.5, tc, 190.3, 160.7, phi, 12.0);
    ASSERT_TRUE(a.valid && b.valid);
    EXPECT_NEAR(a.pos_rms_px() / b.pos_rms_px(), std::sqrt(2.0), 0.02 * std::sqrt(2.0)) << phi;
    EXPECT_NEAR(a.phi_deg() / b.phi_deg(), std::sqrt(2.0), 0.02 * std::sqrt(2.0)) << phi;
  }
}

TEST(Crlb, FlatSceneHasNoBound) {
  const config::TrackerConfig tc;
  const WarpScene flat = synthetic(400, 400, [](int, int) { return 0.5; });
  const Crlb c = crlb_warp(flat, 200, 200, tc, 190.3, 160.7, 10.0, 6.0);
  EXPECT_FALSE(c.valid);
  EXPECT_TRUE(std::isinf(c.pos_rms_px()));
  EXPECT_TRUE(std::isinf(c.phi_deg()));
  // A scene with structure in x only: y is unobservable, so still no bound (and no NaN).
  const WarpScene stripes = synthetic(400, 400, [](int x, int) { return 0.5 + 0.3 * std::sin(x * 0.7); });
  const Crlb s = crlb_warp(stripes, 200, 200, tc, 190.3, 160.7, 0.0, 6.0);
  EXPECT_FALSE(s.valid);
  EXPECT_FALSE(std::isnan(s.pos_rms_px()));
}

// Brightness b0 + a·u² + c·v² + g·v around the scene centre (u, v in the target's frame; the
// odd term g·v makes a wrong turning sense visible): blurred by a Gaussian it stays the same
// quadratic plus a constant, so λ and ∂λ/∂θ are known in closed form (D = dose):
//   u = dx·cosφ − dy·sinφ, v = dx·sinφ + dy·cosφ (dx = px − x, dy = py − y)
//   ∂λ/∂x = −D(2a·u·cosφ + (2c·v + g)·sinφ), ∂λ/∂y = D(2a·u·sinφ − (2c·v + g)·cosφ),
//   ∂λ/∂φ = D(2(c − a)·u·v + g·u) [per rad]
TEST(Crlb, QuadraticSceneMatchesClosedForm) {
  const config::TrackerConfig tc;
  const double a = 2e-5, cq = 5e-5, g = 2e-3, b0 = 0.2, dose = 6.0;
  const double ccx = 250, ccy = 250;
  const WarpScene q =
      synthetic(500, 500, [&](int X, int Y) { return b0 + a * (X - ccx) * (X - ccx) + cq * (Y - ccy) * (Y - ccy) + g * (Y - ccy); });
  for (double phi : {0.0, 30.0}) {
    const double x = 190.3, y = 160.7;
    const Crlb num = crlb_warp(q, ccx, ccy, tc, x, y, phi, dose);
    ASSERT_TRUE(num.valid);
    // Closed form over the same mask.
    const auto use = tracker_mask(tc);
    const int P = tc.pattern_size_px;
    const hal::Roi w = mask_window(x, y, P);
    const double r = phi * M_PI / 180, cs = std::cos(r), sn = std::sin(r), deg = M_PI / 180;
    // The discrete Gaussian's variance (≈ σ² = 1) adds a constant to the blurred quadratic.
    double s0 = 0, s2 = 0;
    for (int i = -3; i <= 3; ++i) {
      s0 += std::exp(-0.5 * i * i);
      s2 += i * i * std::exp(-0.5 * i * i);
    }
    const double var_psf = s2 / s0;
    std::array<std::array<double, 3>, 3> F{};
    for (int py = 0; py < P; ++py)
      for (int px = 0; px < P; ++px) {
        if (!use[static_cast<std::size_t>(py) * P + px]) continue;
        const double dx = w.x + px - x, dy = w.y + py - y;
        const double u = dx * cs - dy * sn, v = dx * sn + dy * cs;
        const double lam = dose * (b0 + (a + cq) * var_psf + a * u * u + cq * v * v + g * v);
        const double j[3] = {-dose * (2 * a * u * cs + (2 * cq * v + g) * sn), dose * (2 * a * u * sn - (2 * cq * v + g) * cs),
                             dose * (2 * (cq - a) * u * v + g * u) * deg};
        for (int i = 0; i < 3; ++i)
          for (int k = 0; k < 3; ++k) F[i][k] += j[i] * j[k] / lam;
      }
    std::array<std::array<double, 3>, 3> C{};
    ASSERT_TRUE(invert_sym3(F, C));
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(num.cov[i][i], C[i][i], 0.02 * C[i][i]) << "phi " << phi << " param " << i;
      for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(num.fisher[i][k], F[i][k], 0.02 * std::sqrt(F[i][i] * F[k][k])) << "phi " << phi << " " << i << k;
    }
  }
}

TEST(Crlb, InvertSym3MatchesHandInverse) {
  const std::array<std::array<double, 3>, 3> A{{{4, 1, 0.5}, {1, 3, 0.2}, {0.5, 0.2, 2}}};
  std::array<std::array<double, 3>, 3> inv{};
  ASSERT_TRUE(invert_sym3(A, inv));
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      double s = 0;
      for (int m = 0; m < 3; ++m) s += A[i][m] * inv[m][k];
      EXPECT_NEAR(s, i == k ? 1.0 : 0.0, 1e-12);
    }
  const std::array<std::array<double, 3>, 3> singular{{{1, 2, 3}, {2, 4, 6}, {3, 6, 10}}};
  EXPECT_FALSE(invert_sym3(singular, inv));
}

TEST(Crlb, SimulatorExcessNoiseRaisesBoundBySqrtOnePlusOneOverK) {
  const config::TrackerConfig tc;
  Scenario s;
  s.target = "lamella_post";
  s.dose_e = 6.0;
  config::SimConfig cfg = make_sim_config(s);
  cfg.read_noise_e = 0;
  cfg.detector_gain_shape = 1e12;  // no gain spread: pure Poisson
  const Crlb poisson = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, tc, 320.2, 240.4, 30.0);
  cfg.detector_gain_shape = 3.0;
  const Crlb gamma3 = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, tc, 320.2, 240.4, 30.0);
  cfg.read_noise_e = 0.3;
  const Crlb with_read = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, tc, 320.2, 240.4, 30.0);
  ASSERT_TRUE(poisson.valid && gamma3.valid && with_read.valid);
  std::printf("simulator lamella_post, dose 6, φ 30: Poisson %.3f px %.3f°, Gamma k=3 %.3f px %.3f°, + read 0.3 e %.3f px %.3f°\n",
              poisson.pos_rms_px(), poisson.phi_deg(), gamma3.pos_rms_px(), gamma3.phi_deg(), with_read.pos_rms_px(),
              with_read.phi_deg());
  EXPECT_NEAR(gamma3.pos_rms_px() / poisson.pos_rms_px(), std::sqrt(1 + 1 / 3.0), 1e-3);
  EXPECT_NEAR(gamma3.phi_deg() / poisson.phi_deg(), std::sqrt(1 + 1 / 3.0), 1e-3);
  EXPECT_GT(with_read.pos_rms_px(), gamma3.pos_rms_px());
  // The simulator's pure-Poisson bound also follows 1/√dose (its renders are in electrons).
  Scenario s2 = s;
  s2.dose_e = 24.0;
  config::SimConfig cfg2 = make_sim_config(s2);
  cfg2.read_noise_e = 0;
  cfg2.detector_gain_shape = 1e12;
  const Crlb poisson24 = crlb_sim_config(cfg2, s2.field_w, s2.field_h, s2.dwell_ns, tc, 320.2, 240.4, 30.0);
  ASSERT_TRUE(poisson24.valid);
  EXPECT_NEAR(poisson.pos_rms_px() / poisson24.pos_rms_px(), 2.0, 0.04);
}

TEST(Crlb, SimulatorBackgroundAloneCarriesNoPoseInformation) {
  const config::TrackerConfig tc;
  Scenario s;
  config::SimConfig cfg = make_sim_config(s);
  cfg.targets[0].enabled = false;
  const Crlb c = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, tc, 320.2, 240.4, 30.0);
  EXPECT_FALSE(c.valid);
  EXPECT_TRUE(std::isinf(c.pos_rms_px()));
}

// The bound's renderer copies SimSource::render's compositing; it must stay equal to it (noise,
// drift and beam lag off), or the bench's bound would describe another scene.
TEST(Crlb, SimMeanRendererEqualsTheSimulatorsNoiseFreeRender) {
  for (const char* target : {"needle_tip", "lamella_post", "lamella"}) {
    Scenario s;
    s.target = target;
    s.dose_e = 6.0;
    config::SimConfig cfg = make_sim_config(s);
    cfg.noise = false;
    cfg.drift.clear();
    cfg.beam_lag_px = 0;
    cfg.brightness_drift = 0;
    cfg.clock = "virtual";
    const double x = 301.37, y = 252.81, phi = -47.3;
    cfg.targets[0].x_px = x;
    cfg.targets[0].y_px = y;
    cfg.targets[0].phi_deg = phi;
    cfg.targets[0].trajectory = config::TrajectoryConfig{};
    hal::ScanLimits lim;
    lim.field_w = s.field_w;
    lim.field_h = s.field_h;
    lim.bits = 16;
    hal::SimSource src(lim, cfg);
    const hal::Roi roi{240, 190, 128, 128};
    std::vector<hal::Pixel> px(128 * 128);
    hal::TargetTruth truth[hal::kMaxTargets];
    src.render(roi, s.dwell_ns, hal::SimSource::kVirtualEpochNs, 0, px.data(), truth);
    const SimMeanRenderer mine(cfg, s.field_w, s.field_h, s.dwell_ns);
    std::vector<double> e;
    mine.render(roi, x, y, phi, e);
    const double n_white = cfg.electrons_per_pixel(s.dwell_ns);
    const double counts_per_e = cfg.output_white * 65535.0 / n_white, offset = cfg.output_offset * 65535.0 + 0.5;
    double worst = 0, spread = 0;
    for (std::size_t i = 0; i < px.size(); ++i) {
      const double expect = std::floor(offset + e[i] * counts_per_e);
      worst = std::max(worst, std::fabs(px[i] - expect));
      spread = std::max(spread, std::fabs(e[i] - e[0]));
    }
    EXPECT_LE(worst, 1.0) << target;      // counts of 65535 (float rounding at a floor)
    EXPECT_GT(spread, 0.5) << target;     // the ROI shows structure (not a blank comparison)
  }
}
