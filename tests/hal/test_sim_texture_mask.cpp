// A texture's threshold mask: `threshold` keeps the largest bright region of the crop (a needle,
// not bright grains); `threshold_all` keeps every region of >= 5 % of the largest too, so a
// needle carrying a lamella across a dark gap is one target with both parts.
#include <gtest/gtest.h>

#include <string>

#include "sempose/hal/sim_scene.hpp"

namespace sempose::hal {
namespace {

// Covered pixels (alpha >= 0.5) of the first target, left and right of column `split` of the
// layer (the needle's tip / the lamella's side of the gap in the crop below).
void covered(const std::string& mask, double split_fraction, int& left, int& right) {
  config::SimConfig c;
  c.targets.assign(1, config::SimTargetConfig{});  // not the default needle: its size and crop
  config::SimTargetConfig& t = c.targets[0];
  t.texture.source = "image";
  t.texture.path = std::string(SEMPOSE_TEST_DATA) + "/sem/needle_lamella_post_eb.pgm";
  // The needle's last ~150 px, the dark gap at x ~ 185-188 of the micrograph, the lamella.
  t.texture.crop_x = 40, t.texture.crop_y = 380, t.texture.crop_w = 360, t.texture.crop_h = 190;
  t.texture.mask = mask;
  t.texture.mask_level = 0.3;
  config::ScanLimits lim;
  lim.field_w = 640, lim.field_h = 480;
  const SimScene scene(c, lim);
  const FloatImage& a = scene.targets()[0].parts[0].alpha;
  const int split = static_cast<int>(a.w * split_fraction);
  left = right = 0;
  for (int y = 0; y < a.h; ++y)
    for (int x = 0; x < a.w; ++x)
      if (a.at(x, y) >= 0.5f) ++(x < split ? left : right);
}

TEST(SimTextureMask, ThresholdAllKeepsTheNeedleAndTheLamellaItCarries) {
  // The gap lies at (186 - 40) / 360 = 0.41 of the crop's width.
  int needle = 0, lamella = 0, needle_all = 0, lamella_all = 0;
  covered("threshold", 0.41, needle, lamella);
  covered("threshold_all", 0.41, needle_all, lamella_all);
  // One region only: one side is (nearly) empty.
  EXPECT_LT(std::min(needle, lamella), 1000) << needle << " / " << lamella;
  // Both parts, each a solid block of thousands of pixels.
  EXPECT_GT(needle_all, 5000);
  EXPECT_GT(lamella_all, 5000);
  EXPECT_EQ(std::max(needle, lamella), std::max(needle_all, lamella_all)) << "the largest region is the same";
}

}  // namespace
}  // namespace sempose::hal
