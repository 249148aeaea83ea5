// The sub-pixel / sub-step fits on synthetic score surfaces with a known peak.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <cmath>

#include "sempose/pose/subpixel_fit.hpp"

using namespace sempose::pose;

namespace {
// A tilted concave quadratic with its peak at (px, py, pj) and value top.
double surface(double x, double y, double j, double px, double py, double pj, double top) {
  const double a = x - px, b = y - py, c = j - pj;
  return top - 0.05 * a * a - 0.03 * b * b - 0.04 * c * c - 0.02 * a * b + 0.01 * a * c - 0.015 * b * c;
}
void samples(double px, double py, double pj, bool exponentiate, float* out) {
  for (int i = 0; i < SubpixelFit::kSamples; ++i) {
    const auto& o = SubpixelFit::kOffsets[i];
    const double v = surface(o[0], o[1], o[2], px, py, pj, 0.8);
    out[i] = static_cast<float>(exponentiate ? std::exp(v) : v);
  }
}
}  // namespace

TEST(SubpixelFit, JointFitFindsAKnownTiltedPeak) {
  const SubpixelFit fit(false, false);
  float s[SubpixelFit::kSamples];
  samples(0.3, -0.2, 0.45, false, s);
  double dx = 0, dy = 0, dj = 0;
  float peak = 0;
  ASSERT_TRUE(fit.joint_fit(s, false, dx, dy, dj, peak));
  EXPECT_NEAR(dx, 0.3, 1e-5);
  EXPECT_NEAR(dy, -0.2, 1e-5);
  EXPECT_NEAR(dj, 0.45, 1e-5);
  EXPECT_NEAR(peak, 0.8, 1e-5);
  // On log scores: a Gaussian-shaped surface is fitted exactly too.
  samples(-0.4, 0.1, -0.25, true, s);
  ASSERT_TRUE(fit.joint_fit(s, true, dx, dy, dj, peak));
  EXPECT_NEAR(dx, -0.4, 1e-5);
  EXPECT_NEAR(dy, 0.1, 1e-5);
  EXPECT_NEAR(dj, -0.25, 1e-5);
}

TEST(SubpixelFit, NoClearMaximumIsRefused) {
  const SubpixelFit fit(false, false);
  float s[SubpixelFit::kSamples];
  double dx = 0, dy = 0, dj = 0;
  float peak = 0;
  // A saddle: up in x.
  for (int i = 0; i < SubpixelFit::kSamples; ++i) {
    const auto& o = SubpixelFit::kOffsets[i];
    s[i] = static_cast<float>(0.5 + 0.05 * o[0] * o[0] - 0.05 * o[1] * o[1] - 0.05 * o[2] * o[2]);
  }
  EXPECT_FALSE(fit.joint_fit(s, false, dx, dy, dj, peak));
  // The peak 3 steps away: outside the sampled cube.
  samples(3.0, 0.0, 0.0, false, s);
  EXPECT_FALSE(fit.joint_fit(s, false, dx, dy, dj, peak));
  // A sample outside the ROI (-2) or a non-positive score on log scores.
  samples(0.1, 0.1, 0.1, false, s);
  s[3] = -2.0f;
  EXPECT_FALSE(fit.joint_fit(s, false, dx, dy, dj, peak));
  samples(0.1, 0.1, 0.1, false, s);
  s[5] = 0.0f;
  EXPECT_FALSE(fit.joint_fit(s, true, dx, dy, dj, peak));
}

TEST(Fit3, ParabolaAndGaussianPeaks) {
  auto parabola = [](double x) { return static_cast<float>(1.0 - 0.1 * (x - 0.3) * (x - 0.3)); };
  EXPECT_NEAR(fit3(parabola(-1), parabola(0), parabola(1), false), 0.3, 1e-6);
  auto gauss = [](double x) { return static_cast<float>(std::exp(-0.2 * (x + 0.2) * (x + 0.2))); };
  EXPECT_NEAR(fit3(gauss(-1), gauss(0), gauss(1), true), -0.2, 1e-6);
  EXPECT_EQ(fit3(0.5f, 0.5f, 0.5f, false), 0.0);   // flat: no offset
  EXPECT_EQ(fit3(0.1f, 0.2f, 0.9f, false), 0.0);   // convex (a valley): no offset
  EXPECT_EQ(fit3(0.0f, 0.5f, 0.6f, false), 0.5);   // peak beyond the right sample: clamped to the half step
}
