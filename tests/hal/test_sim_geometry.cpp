// A target placed at (x, y, φ) renders where the README's conventions say: positive φ turns the pattern
// counter-clockwise on screen (from +x toward −y, image y down) about its centre.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sempose/hal/pgm.hpp"
#include "sempose/hal/sim_source.hpp"
#include "test_util.hpp"

namespace sempose::hal {
namespace {

constexpr int kTexW = 31, kTexH = 21;  // odd: the centre (15, 10) is a pixel

struct Fixture {
  ScanLimits limits;
  config::SimConfig cfg = test::clean_config();
  std::string path;
  Image tex;

  explicit Fixture(const std::string& name, bool dot_only) {
    limits.field_w = limits.field_h = 128;
    limits.max_roi_w = limits.max_roi_h = 128;
    tex.width = kTexW;
    tex.height = kTexH;
    tex.pixels.assign(kTexW * kTexH, 0);
    for (int y = 0; y < kTexH; ++y) {
      for (int x = 0; x < kTexW; ++x) {
        // Asymmetric ramp so every rotation is distinguishable; or a single bright dot.
        tex.pixels[y * kTexW + x] = dot_only ? 0 : static_cast<std::uint16_t>(20 + 5 * x + 3 * y);
      }
    }
    if (dot_only) tex.pixels[10 * kTexW + 25] = 255;  // 10 px to the right of the centre
    path = (test::temp_dir(name) / "tex.pgm").string();
    write_pgm(path, tex);
    config::SimTargetConfig t;
    t.texture.source = "image";
    t.texture.path = path;
    t.texture.mask = "full";
    cfg.targets = {t};
  }
  std::vector<Pixel> render(double x, double y, double phi) {
    cfg.targets[0].x_px = x;
    cfg.targets[0].y_px = y;
    cfg.targets[0].phi_deg = phi;
    SimSource src(limits, cfg);
    std::vector<Pixel> out(128 * 128);
    TargetTruth truth[kMaxTargets];
    src.render({0, 0, 128, 128}, 1000, SimSource::kVirtualEpochNs, 0, out.data(), truth);
    EXPECT_TRUE(truth[0].present);
    EXPECT_DOUBLE_EQ(truth[0].x_px, x);
    EXPECT_DOUBLE_EQ(truth[0].y_px, y);
    return out;
  }
};

// Screen offset of texture offset (dx, dy) after rotating by a multiple of 90° CCW on screen,
// written out case by case (independent of the renderer's matrix).
void rotate_quarter(int quarter, int dx, int dy, int& sx, int& sy) {
  switch (quarter) {
    case 0: sx = dx, sy = dy; break;
    case 1: sx = dy, sy = -dx; break;   // +x (right) goes to −y (up)
    case 2: sx = -dx, sy = -dy; break;
    default: sx = -dy, sy = dx; break;  // −90°: +x goes down
  }
}

TEST(SimGeometry, QuarterTurnsMatchADirectlyRotatedTexture) {
  Fixture f("geom_q", false);
  const double white = f.cfg.output_white * 255, offset = f.cfg.output_offset * 255;
  for (int quarter = 0; quarter < 4; ++quarter) {
    const int X = 60, Y = 70;
    const auto img = f.render(X, Y, quarter == 3 ? -90.0 : 90.0 * quarter);
    int checked = 0;
    for (int ty = 0; ty < kTexH; ++ty) {
      for (int tx = 0; tx < kTexW; ++tx) {
        int sx = 0, sy = 0;
        rotate_quarter(quarter, tx - 15, ty - 10, sx, sy);
        const double expected = offset + f.tex.pixels[ty * kTexW + tx] / 255.0 * white;
        ASSERT_NEAR(img[(Y + sy) * 128 + (X + sx)], expected, 1.0)
            << "quarter " << quarter << " texel (" << tx << "," << ty << ")";
        ++checked;
      }
    }
    EXPECT_EQ(checked, kTexW * kTexH);
    // Outside the target: the black background.
    EXPECT_NEAR(img[5 * 128 + 5], offset, 1.0);
  }
}

TEST(SimGeometry, ArbitraryAngleAndSubpixelPositionMoveTheDotCounterClockwise) {
  Fixture f("geom_dot", true);
  const double offset = f.cfg.output_offset * 255;
  for (double phi : {0.0, 30.0, -50.0, 135.0}) {
    const double X = 60.3, Y = 70.6;
    const auto img = f.render(X, Y, phi);
    double sw = 0, sx = 0, sy = 0;
    for (int y = 0; y < 128; ++y) {
      for (int x = 0; x < 128; ++x) {
        const double w = img[y * 128 + x] - offset;
        if (w > 2) sw += w, sx += w * x, sy += w * y;
      }
    }
    ASSERT_GT(sw, 0);
    const double r = phi * M_PI / 180;
    EXPECT_NEAR(sx / sw, X + 10 * std::cos(r), 0.25) << "phi " << phi;
    EXPECT_NEAR(sy / sw, Y - 10 * std::sin(r), 0.25) << "phi " << phi;
  }
}

TEST(SimGeometry, TargetOutsideTheFieldIsNotPresent) {
  Fixture f("geom_out", false);
  f.cfg.targets[0].x_px = -40;
  SimSource src(f.limits, f.cfg);
  std::vector<Pixel> out(16 * 16);
  TargetTruth truth[kMaxTargets];
  src.render({0, 0, 16, 16}, 1000, SimSource::kVirtualEpochNs, 0, out.data(), truth);
  EXPECT_FALSE(truth[0].present);
  EXPECT_FALSE(truth[1].present);
}

}  // namespace
}  // namespace sempose::hal
