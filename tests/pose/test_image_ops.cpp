// The pose engine's image operations on synthetic input: the one box downsample, the one
// summed-area table, the one angle wrap and the angle grid.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "sempose/pose/angle_grid.hpp"
#include "sempose/pose/box_downsample.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/summed_area_table.hpp"
#include "sempose/rt/angle.hpp"

using namespace sempose;
using namespace sempose::pose;

TEST(BoxDownsample, SumsEachBlockFromTheOffset) {
  const int w = 11, h = 9;
  std::vector<std::uint16_t> src(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) src[y * w + x] = static_cast<std::uint16_t>(100 * y + x);
  std::vector<std::int32_t> out(4 * 2);
  box_downsample<std::uint16_t, std::int32_t, std::int32_t>(src.data(), w, 1, 2, 3, 3, 2, out.data());
  for (int oy = 0; oy < 2; ++oy)
    for (int ox = 0; ox < 3; ++ox) {
      std::int32_t ref = 0;
      for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) ref += src[(2 + 3 * oy + j) * w + 1 + 3 * ox + i];
      EXPECT_EQ(out[oy * 3 + ox], ref) << ox << "," << oy;
    }
  // Float patterns: summed in double, stored as float.
  std::vector<float> f(16, 0.25f), g(4);
  box_downsample<float, double, float>(f.data(), 4, 0, 0, 2, 2, 2, g.data());
  for (float v : g) EXPECT_EQ(v, 1.0f);
}

TEST(SummedAreaTables, EveryRectangleEqualsTheBruteSum) {
  const int w = 37, h = 23;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> u(0, 1 << 20);
  std::vector<std::int32_t> img(static_cast<std::size_t>(w) * h);
  for (auto& v : img) v = u(rng);
  SummedAreaTables t(64, 64);
  t.build(img.data(), w, h, w);
  EXPECT_EQ(t.width(), w);
  EXPECT_EQ(t.height(), h);
  std::int64_t all = 0, all2 = 0;
  for (auto v : img) all += v, all2 += static_cast<std::int64_t>(v) * v;
  EXPECT_EQ(t.total(), all);
  EXPECT_EQ(t.total_squares(), all2);
  // Random rectangles' sums against a direct sum over the image.
  auto check_rects = [&](int n) {
    for (int k = 0; k < n; ++k) {
      int x0 = static_cast<int>(rng() % w), x1 = static_cast<int>(rng() % w);
      int y0 = static_cast<int>(rng() % h), y1 = static_cast<int>(rng() % h);
      if (x0 > x1) std::swap(x0, x1);
      if (y0 > y1) std::swap(y0, y1);
      std::int64_t s = 0, s2 = 0, rs = 0, rs2 = 0;
      t.add_rect(x0, y0, x1, y1, s, s2);
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) rs += img[y * w + x], rs2 += static_cast<std::int64_t>(img[y * w + x]) * img[y * w + x];
      ASSERT_EQ(s, rs);
      ASSERT_EQ(s2, rs2);
    }
  };
  check_rects(500);
  // Signed values (the running sum is taken eight at a time in a vector: its square and carry
  // must hold for negative values too), a width with whole vectors and a tail.
  for (auto& v : img) v -= 1 << 19;
  t.build(img.data(), w, h, w);
  check_rects(200);
  // A region with a row stride and 16-bit pixels.
  std::vector<std::uint16_t> px(static_cast<std::size_t>(w) * h, 7);
  t.build(px.data(), 10, 5, w);
  EXPECT_EQ(t.total(), 7 * 50);
  EXPECT_EQ(t.total_squares(), 49 * 50);
}

// On demand (the exact scorer's use): after attach(), cover() tables only what rectangles are
// about to be read from; every rectangle read after covering it equals the brute sum, whichever
// way the rectangles wander (down: rows added; left, right, up: the whole region tabled), and
// the first cover tables no more than its rectangle and the margin.
TEST(SummedAreaTables, OnDemandRectanglesEqualTheBruteSum) {
  const int w = 61, h = 47, stride = w + 5;
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> u(-(1 << 19), 1 << 19);
  std::vector<std::int32_t> img(static_cast<std::size_t>(stride) * h);
  for (auto& v : img) v = u(rng);
  SummedAreaTables t(64, 64);
  const auto brute = [&](int x0, int y0, int x1, int y1, std::int64_t& s, std::int64_t& s2) {
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) s += img[y * stride + x], s2 += static_cast<std::int64_t>(img[y * stride + x]) * img[y * stride + x];
  };
  for (int trial = 0; trial < 40; ++trial) {
    t.attach(img.data(), w, h, stride);
    const int m = SummedAreaTables::kCoverMargin;
    for (int k = 0; k < 12; ++k) {
      int x0 = static_cast<int>(rng() % w), x1 = static_cast<int>(rng() % w);
      int y0 = static_cast<int>(rng() % h), y1 = static_cast<int>(rng() % h);
      if (x0 > x1) std::swap(x0, x1);
      if (y0 > y1) std::swap(y0, y1);
      t.cover(x0, y0, x1, y1);
      if (k == 0) {
        EXPECT_EQ(t.origin_x(), std::max(0, x0 - m));
        EXPECT_EQ(t.origin_y(), std::max(0, y0 - m));
        EXPECT_EQ(t.width(), std::min(w, x1 + 1 + m) - t.origin_x());
        EXPECT_EQ(t.height(), y1 + 1 - t.origin_y());
      }
      std::int64_t s = 0, s2 = 0, rs = 0, rs2 = 0;
      t.add_rect(x0, y0, x1, y1, s, s2);
      brute(x0, y0, x1, y1, rs, rs2);
      ASSERT_EQ(s, rs) << "trial " << trial << " rectangle " << k;
      ASSERT_EQ(s2, rs2) << "trial " << trial << " rectangle " << k;
    }
  }
  // A full build after on-demand use tables the whole region from its corner again.
  t.build(img.data(), w, h, stride);
  EXPECT_EQ(t.origin_x(), 0);
  EXPECT_EQ(t.width(), w);
  std::int64_t all = 0, all2 = 0;
  brute(0, 0, w - 1, h - 1, all, all2);
  EXPECT_EQ(t.total(), all);
  EXPECT_EQ(t.total_squares(), all2);
}

// The integer prefilter against a plain per-pass reference ([1 4 6 4 1] along x, then along y,
// edges replicated, each pass shifted back to 20 bits): 1-3 passes, a row stride, small and
// odd sizes (the filter streams its rows through a ring).
TEST(Prefilter, EqualsThePlainSeparableFilter) {
  std::mt19937 rng(5);
  const int k[5] = {1, 4, 6, 4, 1};
  for (const int passes : {1, 2, 3})
    for (const auto& [w, h] : {std::pair{37, 23}, std::pair{64, 64}, std::pair{5, 3}, std::pair{9, 1}}) {
      const int stride = w + 3, bits = 14;
      std::uniform_int_distribution<int> u(0, (1 << bits) - 1);
      std::vector<std::uint16_t> src(static_cast<std::size_t>(stride) * h);
      for (auto& v : src) v = static_cast<std::uint16_t>(u(rng));
      std::vector<std::int64_t> a(static_cast<std::size_t>(w) * h), b(a.size());
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) a[y * w + x] = src[y * stride + x];
      int cur = bits;
      for (int p = 0; p < passes; ++p) {
        const int shift = std::max(0, cur + 8 - 20);
        cur = std::min(20, cur + 8);
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            std::int64_t s = 0;
            for (int i = 0; i < 5; ++i) s += k[i] * a[y * w + std::clamp(x + i - 2, 0, w - 1)];
            b[y * w + x] = s;
          }
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            std::int64_t s = 0;
            for (int i = 0; i < 5; ++i) s += k[i] * b[std::clamp(y + i - 2, 0, h - 1) * w + x];
            a[y * w + x] = s >> shift;
          }
      }
      Prefilter f(passes, 64, 64);
      std::vector<std::int32_t> out(static_cast<std::size_t>(w) * h, -1);
      f.apply(src.data(), w, h, stride, bits, out.data());
      for (int i = 0; i < w * h; ++i) ASSERT_EQ(out[i], a[i]) << passes << " passes, " << w << "x" << h << " at " << i;
    }
}

TEST(WrapDeg, IntoTheHalfOpenInterval) {
  EXPECT_EQ(rt::wrap_deg(180.0), 180.0);
  EXPECT_EQ(rt::wrap_deg(-180.0), 180.0);
  EXPECT_EQ(rt::wrap_deg(540.0), 180.0);
  EXPECT_EQ(rt::wrap_deg(-190.0), 170.0);
  EXPECT_EQ(rt::wrap_deg(359.5), -0.5);
  EXPECT_EQ(rt::wrap_deg(0.0), 0.0);
  // Exact: the same bits as the remainder-based wrap the pose filter used before.
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-5000, 5000);
  for (int k = 0; k < 100000; ++k) {
    const double a = u(rng);
    double r = std::remainder(a, 360.0);
    if (r <= -180.0) r += 360.0;
    ASSERT_EQ(rt::wrap_deg(a), r) << a;
  }
}

TEST(AngleGrid, WrapsIndicesAndRoundsAngles) {
  const AngleGrid g{180, 2.0};
  EXPECT_EQ(g.wrap(-1), 179);
  EXPECT_EQ(g.wrap(180), 0);
  EXPECT_EQ(g.wrap(-361), 179);
  EXPECT_EQ(g.index_of(3.1), 2);
  EXPECT_EQ(g.index_of(-2.0), 179);
  EXPECT_EQ(g.index_of(359.0), 0);  // 179.5 rounds to 180 → 0
}
