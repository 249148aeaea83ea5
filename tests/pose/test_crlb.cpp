// The Cramér–Rao bound helper (crlb.hpp) against what must hold whatever the scene: the
// 1/√dose law, no bound for a scene without structure (or with only the static background),
// the analytic Fisher information of a quadratic scene with and without the photometric
// nuisances, nuisances that can only raise the bound, a support that is the blurred target,
// and the detector's excess noise.
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

constexpr int kP = 128;  // the pattern side (the warped scene's recorded crop)

TEST(Crlb, RealSemLamellaAtDose6IsFiniteAndPrinted) {
  const Crlb c = crlb_warp(lamella(), 563.5, 527.5, kP, 190.3, 160.7, 0.0, 6.0);
  ASSERT_TRUE(c.valid);
  EXPECT_EQ(c.n_params, 5);  // x, y, φ, gain, offset
  std::printf("lamella_on_post crop, dose 6, φ 0: sd_x %.3f sd_y %.3f px, 2-D %.3f px, φ %.3f° over %d px\n", c.sd_x_px(),
              c.sd_y_px(), c.pos_rms_px(), c.phi_deg(), c.pixels);
  // The support is the recorded crop's footprint: P² pixels (± its rim).
  EXPECT_NEAR(c.pixels, kP * kP, 4 * kP + 4);
  // Covariance is positive definite: correlations within (−1, 1).
  for (int a = 0; a < c.n_params; ++a)
    for (int b = a + 1; b < c.n_params; ++b) EXPECT_LT(std::fabs(c.cov[a][b]) / std::sqrt(c.cov[a][a] * c.cov[b][b]), 1.0);
  EXPECT_TRUE(std::isfinite(c.pos_rms_px()));
  EXPECT_GT(c.pos_rms_px(), 0.0);
}

TEST(Crlb, PoissonBoundScalesAsOneOverSqrtDose) {
  for (double phi : {0.0, 37.0}) {
    const Crlb a = crlb_warp(lamella(), 563.5, 527.5, kP, 190.3, 160.7, phi, 6.0);
    const Crlb b = crlb_warp(lamella(), 563.5, 527.5, kP, 190.3, 160.7, phi, 12.0);
    ASSERT_TRUE(a.valid && b.valid);
    EXPECT_NEAR(a.pos_rms_px() / b.pos_rms_px(), std::sqrt(2.0), 0.02 * std::sqrt(2.0)) << phi;
    EXPECT_NEAR(a.phi_deg() / b.phi_deg(), std::sqrt(2.0), 0.02 * std::sqrt(2.0)) << phi;
  }
}

TEST(Crlb, FlatSceneHasNoBound) {
  const WarpScene flat = synthetic(400, 400, [](int, int) { return 0.5; });
  const Crlb c = crlb_warp(flat, 200, 200, kP, 190.3, 160.7, 10.0, 6.0);
  EXPECT_FALSE(c.valid);
  EXPECT_TRUE(std::isinf(c.pos_rms_px()));
  EXPECT_TRUE(std::isinf(c.phi_deg()));
  // A scene with structure in x only: y is unobservable, so still no bound (and no NaN).
  const WarpScene stripes = synthetic(400, 400, [](int x, int) { return 0.5 + 0.3 * std::sin(x * 0.7); });
  const Crlb s = crlb_warp(stripes, 200, 200, kP, 190.3, 160.7, 0.0, 6.0);
  EXPECT_FALSE(s.valid);
  EXPECT_FALSE(std::isnan(s.pos_rms_px()));
}

// Brightness b0 + a·u² + c·v² + g·v around the scene centre (u, v in the target's frame; the
// odd term g·v makes a wrong turning sense visible): blurred by a Gaussian it stays the same
// quadratic plus a constant, so λ and ∂λ/∂θ are known in closed form (D = dose):
//   u = dx·cosφ − dy·sinφ, v = dx·sinφ + dy·cosφ (dx = px − x, dy = py − y)
//   ∂λ/∂x = −D(2a·u·cosφ + (2c·v + g)·sinφ), ∂λ/∂y = D(2a·u·sinφ − (2c·v + g)·cosφ),
//   ∂λ/∂φ = D(2(c − a)·u·v + g·u) [per rad], ∂λ/∂gain = D·b, ∂λ/∂offset = D
// summed over the footprint |u|, |v| ≤ P/2.
TEST(Crlb, QuadraticSceneMatchesClosedFormWithAndWithoutNuisances) {
  const double a = 2e-5, cq = 5e-5, g = 2e-3, b0 = 0.2, dose = 6.0;
  const double ccx = 250, ccy = 250;
  const WarpScene q =
      synthetic(500, 500, [&](int X, int Y) { return b0 + a * (X - ccx) * (X - ccx) + cq * (Y - ccy) * (Y - ccy) + g * (Y - ccy); });
  // The discrete Gaussian's variance (≈ σ² = 1) adds a constant to the blurred quadratic.
  double s0 = 0, s2 = 0;
  for (int i = -3; i <= 3; ++i) {
    s0 += std::exp(-0.5 * i * i);
    s2 += i * i * std::exp(-0.5 * i * i);
  }
  const double var_psf = s2 / s0;
  for (bool photometric : {false, true}) {
    for (double phi : {0.0, 30.0}) {
      const double x = 190.3, y = 160.7;
      CrlbNuisance nu;
      nu.photometric = photometric;
      const Crlb num = crlb_warp(q, ccx, ccy, kP, x, y, phi, dose, nu);
      ASSERT_TRUE(num.valid);
      const int n = photometric ? 5 : 3;
      ASSERT_EQ(num.n_params, n);
      const double r = phi * M_PI / 180, cs = std::cos(r), sn = std::sin(r), deg = M_PI / 180;
      CrlbMatrix F{};
      int pixels = 0;
      for (int py = static_cast<int>(y) - 100; py < static_cast<int>(y) + 100; ++py)
        for (int px = static_cast<int>(x) - 100; px < static_cast<int>(x) + 100; ++px) {
          const double dx = px - x, dy = py - y;
          const double u = dx * cs - dy * sn, v = dx * sn + dy * cs;
          if (std::fabs(u) > kP / 2.0 || std::fabs(v) > kP / 2.0) continue;
          ++pixels;
          const double bright = b0 + (a + cq) * var_psf + a * u * u + cq * v * v + g * v;
          const double lam = dose * bright;
          const double j[5] = {-dose * (2 * a * u * cs + (2 * cq * v + g) * sn), dose * (2 * a * u * sn - (2 * cq * v + g) * cs),
                               dose * (2 * (cq - a) * u * v + g * u) * deg, dose * bright, dose};
          for (int i = 0; i < n; ++i)
            for (int k = 0; k < n; ++k) F[i][k] += j[i] * j[k] / lam;
        }
      EXPECT_EQ(num.pixels, pixels);
      CrlbMatrix C{};
      ASSERT_TRUE(invert_spd(F, n, C));
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(num.cov[i][i], C[i][i], 0.02 * C[i][i]) << "phi " << phi << " param " << i;
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < n; ++k)
          EXPECT_NEAR(num.fisher[i][k], F[i][k], 0.02 * std::sqrt(F[i][i] * F[k][k])) << "phi " << phi << " " << i << k;
    }
  }
}

TEST(Crlb, InvertSpdMatchesTheIdentityAndRejectsSingular) {
  const CrlbMatrix A{{{4, 1, 0.5, 0.1, 0, 0, 0}, {1, 3, 0.2, 0, 0.3, 0, 0}, {0.5, 0.2, 2, 0.4, 0, 0, 0},
                      {0.1, 0, 0.4, 5, 1, 0, 0}, {0, 0.3, 0, 1, 6, 0, 0}}};
  CrlbMatrix inv{};
  ASSERT_TRUE(invert_spd(A, 5, inv));
  for (int i = 0; i < 5; ++i)
    for (int k = 0; k < 5; ++k) {
      double s = 0;
      for (int m = 0; m < 5; ++m) s += A[i][m] * inv[m][k];
      EXPECT_NEAR(s, i == k ? 1.0 : 0.0, 1e-12);
    }
  const CrlbMatrix singular{{{1, 2, 3}, {2, 4, 6}, {3, 6, 10}}};
  EXPECT_FALSE(invert_spd(singular, 3, inv));
}

// Estimating more parameters can only cost pose information: the bound with the nuisances is
// never below the bound without them (on the real SEM crop and on the simulator's targets).
TEST(Crlb, NuisancesOnlyRaiseTheBound) {
  CrlbNuisance none;
  none.photometric = false;
  const Crlb w0 = crlb_warp(lamella(), 563.5, 527.5, kP, 190.3, 160.7, 20.0, 6.0, none);
  const Crlb w1 = crlb_warp(lamella(), 563.5, 527.5, kP, 190.3, 160.7, 20.0, 6.0);
  ASSERT_TRUE(w0.valid && w1.valid);
  for (int i = 0; i < 3; ++i) EXPECT_GE(w1.cov[i][i], w0.cov[i][i] * (1 - 1e-9)) << i;
  std::printf("warped crop dose 6: no nuisance %.4f px %.4f°, + gain/offset %.4f px %.4f°\n", w0.pos_rms_px(), w0.phi_deg(),
              w1.pos_rms_px(), w1.phi_deg());
  for (const char* target : {"lamella_post", "needle_tip"}) {
    Scenario s;
    s.target = target;
    const SimMeanRenderer sim(make_sim_config(s), s.field_w, s.field_h, s.dwell_ns);
    SimState st;
    st.x = 320.2, st.y = 240.4, st.phi_deg = 30, st.scale = 1.1;
    CrlbNuisance with_scale;
    with_scale.scale = true;
    const Crlb a = crlb_sim(sim, st, none), b = crlb_sim(sim, st), c = crlb_sim(sim, st, with_scale);
    ASSERT_TRUE(a.valid && b.valid && c.valid) << target;
    EXPECT_EQ(c.n_params, 6);
    for (int i = 0; i < 3; ++i) {
      EXPECT_GE(b.cov[i][i], a.cov[i][i] * (1 - 1e-9)) << target << " " << i;
      EXPECT_GE(c.cov[i][i], b.cov[i][i] * (1 - 1e-9)) << target << " " << i;
    }
    // Scale and position are entangled where the target is not symmetric about its pose point.
    EXPECT_GT(c.var_pos_px2(), 1.001 * b.var_pos_px2()) << target;
    std::printf("simulator %s dose 6: pose only %.4f px %.4f°, + gain/offset %.4f px %.4f°, + scale %.4f px %.4f°\n", target,
                a.pos_rms_px(), a.phi_deg(), b.pos_rms_px(), b.phi_deg(), c.pos_rms_px(), c.phi_deg());
  }
}

// The support is every pixel the target changes: its footprint grown by the PSF, turned and
// scaled with it — more than the tracker's mask sees of a small target, and it grows with scale.
TEST(Crlb, SupportIsTheBlurredTargetFootprint) {
  Scenario s;
  s.target = "lamella_post";  // a 100×100 square, full mask
  const SimMeanRenderer sim(make_sim_config(s), s.field_w, s.field_h, s.dwell_ns);
  SimState st;
  st.x = 320.2, st.y = 240.4, st.phi_deg = 0;
  const Crlb a = crlb_sim(sim, st);
  st.scale = 1.25;
  const Crlb b = crlb_sim(sim, st);
  st.scale = 1.0;
  st.defocus_px = 2.0;
  const Crlb c = crlb_sim(sim, st);
  ASSERT_TRUE(a.valid && b.valid && c.valid);
  // 100² plus a rim where the PSF (σ 0.8) and bilinear sampling spread it.
  EXPECT_GT(a.pixels, 100 * 100);
  EXPECT_LT(a.pixels, 108 * 108);
  EXPECT_NEAR(static_cast<double>(b.pixels) / a.pixels, 1.25 * 1.25, 0.06);
  EXPECT_GT(c.pixels, a.pixels + 4 * 100 * 3);  // defocus spreads it ≥ 3 px further each side
  EXPECT_GT(c.pos_rms_px(), a.pos_rms_px());   // and blurs the edges that carry the information
}

TEST(Crlb, SimulatorExcessNoiseRaisesBoundBySqrtOnePlusOneOverK) {
  Scenario s;
  s.target = "lamella_post";
  s.dose_e = 6.0;
  config::SimConfig cfg = make_sim_config(s);
  cfg.read_noise_e = 0;
  cfg.detector_gain_shape = 1e12;  // no gain spread: pure Poisson
  const Crlb poisson = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, 320.2, 240.4, 30.0);
  cfg.detector_gain_shape = 3.0;
  const Crlb gamma3 = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, 320.2, 240.4, 30.0);
  cfg.read_noise_e = 0.3;
  const Crlb with_read = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, 320.2, 240.4, 30.0);
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
  const Crlb poisson24 = crlb_sim_config(cfg2, s2.field_w, s2.field_h, s2.dwell_ns, 320.2, 240.4, 30.0);
  ASSERT_TRUE(poisson24.valid);
  EXPECT_NEAR(poisson.pos_rms_px() / poisson24.pos_rms_px(), 2.0, 0.04);
}

TEST(Crlb, SimulatorBackgroundAloneCarriesNoPoseInformation) {
  Scenario s;
  config::SimConfig cfg = make_sim_config(s);
  cfg.targets[0].enabled = false;
  const Crlb c = crlb_sim_config(cfg, s.field_w, s.field_h, s.dwell_ns, 320.2, 240.4, 30.0);
  EXPECT_FALSE(c.valid);
  EXPECT_EQ(c.pixels, 0);
  EXPECT_TRUE(std::isinf(c.pos_rms_px()));
}
