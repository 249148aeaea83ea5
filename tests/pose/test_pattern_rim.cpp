// The setup warning for a pattern whose position information lies at its rim (pattern_rim.hpp):
// a target reaching the rim is placed by the background recorded beyond its ends.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "sempose/pose/pattern_rim.hpp"
#include "sempose/pose/tracker.hpp"

namespace {

using sempose::pose::PatternImage;

// A bright w×h plate centred in an n×n pattern over a smooth random background (its own
// texture, like a substrate's), with a little noise: what `sempose pattern` records.
PatternImage plate(int n, int w, int h, std::uint32_t seed = 7) {
  std::vector<double> bg(static_cast<std::size_t>(n) * n);
  std::uint32_t s = seed;
  auto uniform = [&s] {
    s = s * 1664525u + 1013904223u;
    return static_cast<double>(s >> 8) / 16777216.0;
  };
  for (auto& v : bg) v = uniform();
  for (int pass = 0; pass < 3; ++pass) {  // a smooth texture of a few px
    std::vector<double> o(bg.size());
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        double sum = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx)
            sum += bg[static_cast<std::size_t>(std::clamp(y + dy, 0, n - 1)) * n + std::clamp(x + dx, 0, n - 1)];
        o[static_cast<std::size_t>(y) * n + x] = sum / 9.0;
      }
    bg.swap(o);
  }
  PatternImage im;
  im.width = im.height = n;
  im.pixels.assign(bg.size(), 0);
  const double c = (n - 1) / 2.0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const bool on = std::fabs(x - c) <= w / 2.0 && std::fabs(y - c) <= h / 2.0;
      const double v = 60.0 + 120.0 * (bg[static_cast<std::size_t>(y) * n + x] - 0.5) + (on ? 110.0 : 0.0) + 4.0 * (uniform() - 0.5);
      im.pixels[static_cast<std::size_t>(y) * n + x] = static_cast<std::uint16_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  return im;
}

sempose::pose::RimShare share_of(const PatternImage& im) {
  return sempose::pose::rim_information_share(im.pixels.data(), im.width, sempose::config::TrackerConfig{}.prefilter_passes);
}

}  // namespace

// The plate's ends on the rim: most of the information along its length lies there.
TEST(PatternRim, PlateReachingTheRimIsNamedAlongItsLength) {
  const sempose::pose::RimShare along_x = share_of(plate(64, 60, 36));
  std::printf("plate 60x36 in 64: x %.2f y %.2f (ring area %.2f, %d px)\n", along_x.x, along_x.y, along_x.area, along_x.ring_px);
  ASSERT_TRUE(along_x.valid);
  EXPECT_GE(along_x.x, sempose::pose::kRimShareWarn);
  EXPECT_LT(along_x.y, sempose::pose::kRimShareWarn);
  const std::string w = sempose::pose::rim_warning(along_x);
  EXPECT_NE(w.find("along x"), std::string::npos) << w;
  EXPECT_NE(w.find("outer 4 px"), std::string::npos) << w;
  EXPECT_NE(w.find("shape mask"), std::string::npos) << w;

  const sempose::pose::RimShare along_y = share_of(plate(64, 36, 60));
  EXPECT_GE(along_y.y, sempose::pose::kRimShareWarn);
  EXPECT_NE(sempose::pose::rim_warning(along_y).find("along y"), std::string::npos);
}

// The same plate with a margin, and a plate-free texture, say nothing: their rims hold about
// the ring's share of the area.
TEST(PatternRim, PlateWithAMarginOrPlainTextureIsNotNamed) {
  for (const auto& [w, h] : {std::pair{36, 24}, std::pair{44, 30}, std::pair{0, 0}}) {
    const sempose::pose::RimShare r = share_of(plate(64, w, h));
    std::printf("plate %dx%d in 64: x %.2f y %.2f (ring area %.2f)\n", w, h, r.x, r.y, r.area);
    ASSERT_TRUE(r.valid);
    EXPECT_LT(std::max(r.x, r.y), sempose::pose::kRimShareWarn);
    EXPECT_EQ(sempose::pose::rim_warning(r), "");
  }
  const sempose::pose::RimShare big = share_of(plate(128, 72, 48));
  EXPECT_EQ(sempose::pose::rim_warning(big), "") << big.x << " " << big.y;
}

TEST(PatternRim, FlatPatternHasNoShare) {
  PatternImage flat;
  flat.width = flat.height = 32;
  flat.pixels.assign(32 * 32, 100);
  EXPECT_FALSE(share_of(flat).valid);
  EXPECT_EQ(sempose::pose::rim_warning(share_of(flat)), "");
}

// The tracker's setup says it (run and replay print the trackers' warnings), naming the set;
// not when a shape mask says which pixels are the target.
TEST(PatternRim, TrackerSetupWarnsUnlessAShapeMaskIsGiven) {
  sempose::config::TrackerConfig c;
  c.pattern_size_px = 64;
  c.roi_size_px = 96;
  sempose::config::ScanLimits lim;
  lim.field_w = 320;
  lim.field_h = 240;
  std::vector<sempose::pose::PatternSet> sets(1);
  sets[0].image = plate(64, 60, 36);
  sempose::rt::Status st;
  ASSERT_NE(sempose::pose::Tracker::create(c, sets, lim, st), nullptr) << st.message;
  EXPECT_NE(st.message.find("pattern set 0: "), std::string::npos) << st.message;
  EXPECT_NE(st.message.find("along x"), std::string::npos) << st.message;

  sets[0].image = plate(64, 60, 36);
  sets[0].mask.width = sets[0].mask.height = 64;
  sets[0].mask.pixels.assign(64 * 64, 0);
  for (int y = 14; y < 50; ++y)
    for (int x = 2; x < 62; ++x) sets[0].mask.pixels[static_cast<std::size_t>(y) * 64 + x] = 255;
  ASSERT_NE(sempose::pose::Tracker::create(c, sets, lim, st), nullptr) << st.message;
  EXPECT_EQ(st.message.find("outer"), std::string::npos) << st.message;

  sets[0].image = plate(64, 36, 24);
  sets[0].mask = {};
  ASSERT_NE(sempose::pose::Tracker::create(c, sets, lim, st), nullptr) << st.message;
  EXPECT_EQ(st.message.find("outer"), std::string::npos) << st.message;
}
