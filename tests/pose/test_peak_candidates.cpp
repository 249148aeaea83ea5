// Peak, PSR and start-search candidates on synthetic maps.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "sempose/pose/candidate_list.hpp"
#include "sempose/pose/peak_finder.hpp"

using namespace sempose::pose;

namespace {
std::vector<float> noise_map(int w, int h, unsigned seed, float sd) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.0f, sd);
  std::vector<float> m(static_cast<std::size_t>(w) * h);
  for (auto& v : m) v = n(rng);
  return m;
}
}  // namespace

TEST(FindPeak, MaximumAndPeakToSidelobeRatio) {
  const int w = 40, h = 30;
  auto map = noise_map(w, h, 1, 0.05f);
  map[12 * w + 27] = 0.9f;
  const Peak p = find_peak(map.data(), w, h);
  EXPECT_EQ(p.ux, 27);
  EXPECT_EQ(p.uy, 12);
  EXPECT_EQ(p.score, 0.9f);
  ASSERT_TRUE(p.psr_valid);
  EXPECT_NEAR(p.psr, 0.9 / 0.05, 3.0);  // (peak − mean) / sd of the sidelobe
  // A window that excludes the peak finds the best inside it.
  const Peak q = find_peak(map.data(), w, h, {0, 0, 10, 10});
  EXPECT_LE(q.ux, 10);
  EXPECT_LE(q.uy, 10);
  EXPECT_LT(q.score, 0.9f);
  // A flat sidelobe: the ratio saturates instead of dividing by zero.
  std::vector<float> flat(static_cast<std::size_t>(w) * h, 0.1f);
  flat[5 * w + 5] = 0.5f;
  EXPECT_EQ(find_peak(flat.data(), w, h).psr, 1000.0f);
  // Too small a map for a sidelobe: no PSR.
  EXPECT_FALSE(find_peak(flat.data(), 4, 4).psr_valid);
}

TEST(CandidateList, StrongestSeparatedLocalMaxima) {
  const int w = 30, h = 20;
  std::vector<float> map(static_cast<std::size_t>(w) * h, 0.0f);
  map[5 * w + 5] = 0.5f;
  map[5 * w + 7] = 0.6f;   // within separation 4 of (5,5): replaces it
  map[15 * w + 20] = 0.4f;
  map[2 * w + 25] = 0.3f;
  map[10 * w + 12] = 0.2f;  // fourth: dropped, capacity 3
  map[18 * w + 2] = -0.9f;  // negative: never a candidate
  CandidateList list(3, 4);
  list.add_local_maxima(map.data(), w, h, 2);
  ASSERT_EQ(list.size(), 3);
  EXPECT_EQ(list[0].ux, 7);
  EXPECT_EQ(list[0].k, 2);
  EXPECT_EQ(list[1].score, 0.4f);
  EXPECT_EQ(list[2].score, 0.3f);
  // A better one at a known place replaces it and the order holds.
  list.insert({21, 14, 5, 0.8f});
  EXPECT_EQ(list.size(), 3);
  EXPECT_EQ(list[0].score, 0.8f);
  EXPECT_EQ(list[0].k, 5);
  list.clear();
  EXPECT_EQ(list.size(), 0);
}
