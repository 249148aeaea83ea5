// Accuracy on the simulated SEM (closed loop, ground truth): tracked share, RMS/max errors,
// jump recovery, per doses and motions; plus the sub-pixel peak-fit bias. Printed figures;
// exits non-zero only when something is broken (NaN, crash), never on a figure.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "sim_harness.hpp"

using namespace sempose;
using namespace sempose::pose;
using namespace sempose::pose::testing;

int main(int argc, char** argv) {
  bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  config::TrackerConfig tc;
  const int frames = quick ? 60 : 150;
  std::printf("accuracy on the simulated SEM: 640x480 field, needle texture (%s), pattern %d², ROI %d², "
              "250 ns dwell, %d frames per run\n",
              "lamella_on_post_eb.pgm crop 420,460 180x180 shown at 100x100", tc.pattern_size_px, tc.roi_size_px, frames);
  std::printf("%-7s %5s | %8s %6s %8s %8s %8s %8s %6s %8s\n", "motion", "dose", "tracked", "search", "rms_px",
              "max_px", "rms_deg", "max_deg", "recov", "bias_px");
  int bad = 0;
  for (const char* motion : {"smooth", "fast", "spin", "jump"}) {
    for (double dose : {20.0, 6.0, 2.5, 1.0}) {
      Scenario s;
      s.motion = motion;
      s.dose_e = dose;
      s.frames = frames;
      s.start_phi_deg = 30;
      SimHarness h(s, tc);
      if (!h.status().ok) {
        std::printf("tracker setup failed: %s\n", h.status().message.c_str());
        return 1;
      }
      h.run();
      const RunStats r = h.stats();
      for (const auto& e : h.poses())
        if (!std::isfinite(e.x_px) || !std::isfinite(e.phi_deg) || !std::isfinite(e.score)) ++bad;
      char recov[16] = "-";
      if (r.jumps) std::snprintf(recov, sizeof recov, "%d", r.recovery_max);
      std::printf("%-7s %5.1f | %7.1f%% %6d %8.3f %8.3f %8.3f %8.3f %6s %+8.3f\n", motion, dose,
                  100.0 * r.tracked_share(), r.searches, r.rms_px(), r.max_px, r.rms_deg(), r.max_deg, recov,
                  r.err_n ? std::hypot(r.sum_dx, r.sum_dy) / r.err_n : 0.0);
      std::fflush(stdout);
    }
  }
  // Sub-pixel bias: a static target at fractional positions, noise off; error vs. offset.
  std::printf("\nsub-pixel peak-fit bias (noise off, static target at x = 320 + f, y = 240 + f):\n");
  for (const char* fit : {"gaussian", "quadratic"}) {
    config::TrackerConfig t2 = tc;
    t2.subpixel = fit;
    double worst = 0, sum2 = 0;
    int n = 0;
    std::printf("  %-9s", fit);
    for (int k = 0; k <= 10; k += 2) {
      Scenario s;
      s.motion = "static";
      s.noise = false;
      s.frames = 3;
      s.start_x_px = 320 + k / 10.0;
      s.start_y_px = 240 + k / 10.0;
      SimHarness h(s, t2);
      h.run();
      const auto& e = h.poses().back();
      const auto& tr = h.truth().back();
      const double ex = e.x_px - tr.x_px;
      std::printf(" f=%.1f:%+.3f", k / 10.0, ex);
      worst = std::max(worst, std::fabs(ex));
      sum2 += ex * ex;
      ++n;
    }
    std::printf("  | max %.3f px rms %.3f px\n", worst, std::sqrt(sum2 / n));
  }
  return bad ? 2 : 0;
}
