// `sempose sim` records full-field frames whose scan lasts tens of ms: the truth it writes must
// be where the frame shows a moving target (the pose when the beam passed its pose point), not
// its pose at mid-scan, which for a target near the field's top is several px away.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sempose/hal/sim_source.hpp"

namespace sempose::hal {
namespace {

// A bright procedural lamella on a flat background, no noise, drift or lag: the rendered frame
// shows exactly where the target was when each line was scanned.
config::SimConfig moving_lamella(double y_px) {
  config::SimConfig c;
  c.clock = "virtual";
  c.noise = false;
  c.drift.clear();
  c.beam_lag_px = 0;
  c.brightness_drift = 0;
  c.background.contrast = 0;
  c.targets.clear();
  config::SimTargetConfig a;
  a.texture.source = "lamella";
  a.width_px = 40, a.height_px = 24;
  a.x_px = 200, a.y_px = y_px;
  a.trajectory.kind = "linear";
  a.trajectory.vx_px_s = 300;  // ~23 px over one 640x480 scan at 250 ns
  a.trajectory.margin_px = 30;
  c.targets = {a};
  return c;
}

// The x centroid of the target's brightness above the background on the rows around row y.
double centroid_x(const std::vector<Pixel>& img, int w, int y) {
  double bg = img[static_cast<std::size_t>(y) * w + 5];
  double s = 0, sx = 0;
  for (int r = y - 3; r <= y + 3; ++r) {
    for (int x = 0; x < w; ++x) {
      const double v = img[static_cast<std::size_t>(r) * w + x] - bg;
      if (v > 2) s += v, sx += v * x;
    }
  }
  return s > 0 ? sx / s : -1;
}

TEST(SimTruthTiming, FullFieldTruthIsWhereTheFrameShowsTheTarget) {
  ScanLimits lim;
  lim.field_w = 640;
  lim.field_h = 480;
  for (const double y : {60.0, 240.0, 420.0}) {
    SimSource src(lim, moving_lamella(y));
    FramePool pool(1, 640 * 480);
    const Roi field{0, 0, 640, 480};
    src.advance_virtual_ns(200'000'000);  // the target is moving, away from its start
    ASSERT_EQ(src.start({field, 250, 0}, pool[0]), StartResult::kStarted);
    while (src.poll() != PollResult::kDone) {
    }
    std::vector<Pixel> img(pool[0].pixels, pool[0].pixels + 640 * 480);
    const TargetTruth mid = pool[0].meta.truth[0];
    const TargetTruth seen = src.truth_as_scanned(0, field, 250, pool[0].meta.t_scan_start_ns);
    ASSERT_TRUE(seen.present);
    const double shown = centroid_x(img, 640, static_cast<int>(std::lround(seen.y_px)));
    // The lamella's texture is not symmetric (a thicker frame on one side): its centroid sits a
    // fixed offset from the pose point, the same in every frame; compare the difference.
    SimSource still(lim, [&] { auto c = moving_lamella(y); c.targets[0].trajectory.kind = "static"; return c; }());
    ASSERT_EQ(still.start({field, 250, 0}, pool[0]), StartResult::kStarted);
    while (still.poll() != PollResult::kDone) {
    }
    std::vector<Pixel> ref(pool[0].pixels, pool[0].pixels + 640 * 480);
    const double offset = centroid_x(ref, 640, static_cast<int>(std::lround(y))) - 200.0;
    EXPECT_NEAR(shown - offset, seen.x_px, 0.3) << "row " << y;
    if (y != 240.0) {
      EXPECT_GT(std::fabs(shown - offset - mid.x_px), 5.0) << "mid-scan truth should be off at row " << y;
    }
  }
}

}  // namespace
}  // namespace sempose::hal
