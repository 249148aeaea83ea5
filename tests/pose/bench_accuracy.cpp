// Accuracy on the simulated SEM (closed loop, ground truth): tracked share, start searches,
// RMS/max errors, jump recovery and false TRACKING poses per target texture, motion and dose;
// then the sub-pixel / angle bias, simulator-free (a real SEM crop warped to exact poses) and
// on the simulator. Next to the measured RMS errors: the Cramér–Rao bound of a single frame
// (crlb.hpp) at the run's true poses, and the efficiency bound/measured. Printed figures;
// exits non-zero only when something is broken (NaN, crash), never on a figure.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive in std::vector<float>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "crlb.hpp"
#include "sim_harness.hpp"
#include "warp_scene.hpp"

using namespace sempose;
using namespace sempose::pose;
using namespace sempose::pose::testing;

namespace {

double angle_error(double a, double b) { return std::fmod(a - b + 540.0, 360.0) - 180.0; }

// Mean error (x, y in the target's own frame, φ) over sub-pixel phases: the bias.
struct Bias {
  double along = 0, across = 0, phi = 0, rms_px = 0, rms_deg = 0;
};

// The single-frame bound along a run: the variances averaged over every 15th frame's true pose
// (the bound changes a little with the angle and with the background under the mask).
double g_bound_s = 0;  // time spent computing bounds (its share of the bench's run time is printed)

// POSE_DUMP=<file> in the environment: every pose the bench computes, at full precision
// (hex floats), one line each, tagged with its case: diffing two dumps shows whether a change
// to the tracker moved any pose by even one bit.
std::FILE* g_dump = nullptr;
void dump_pose(const char* tag, const PoseEstimate& e) {
  if (!g_dump) return;
  std::fprintf(g_dump, "%s st%d s%d rb%02x steps%d %a %a %a %a %a %a %a %a\n", tag, static_cast<int>(e.state),
               e.searched, e.reason_bits, e.angle_steps, e.x_px, e.y_px, e.phi_deg, e.meas_x_px, e.meas_y_px,
               e.meas_phi_deg, static_cast<double>(e.score), static_cast<double>(e.psr));
}

CrlbMean run_bound(const Scenario& s, const config::TrackerConfig& tc, const std::vector<hal::TargetTruth>& truth) {
  const std::int64_t t0 = rt::now_ns();
  const SimMeanRenderer sim(make_sim_config(s), s.field_w, s.field_h, s.dwell_ns);
  CrlbMean m;
  for (std::size_t f = 0; f < truth.size(); f += 15) {
    if (!truth[f].present) continue;
    m.add(crlb_sim(sim, s.field_w, s.field_h, tc, truth[f].x_px, truth[f].y_px, truth[f].phi_deg));
  }
  g_bound_s += (rt::now_ns() - t0) * 1e-9;
  return m;
}

// "1.234" or "inf" (no bound: the pose is not observable from the mask's pixels).
std::string fmt(double v, const char* f = "%.3f") {
  if (!std::isfinite(v)) return "inf";
  char b[32];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

Bias warp_bias(const config::TrackerConfig& tc, double phi, double dose, int n) {
  static const WarpScene scene = WarpScene::load(std::string(SEMPOSE_TEST_DATA) + "/sem/lamella_on_post_eb.pgm", 1.0);
  const double cx = 563.5, cy = 527.5;
  constexpr int fw = 384, fh = 320;
  std::vector<PatternSet> sets(1);
  sets[0].image = pipeline::to_pattern_image(scene.pattern(cx, cy, tc.pattern_size_px));
  hal::ScanLimits lim;
  lim.field_w = fw;
  lim.field_h = fh;
  rt::Status st;
  auto tracker = Tracker::create(tc, std::move(sets), lim, st);
  Bias b;
  if (!tracker) return b;
  std::vector<hal::Pixel> field, roi;
  const double c = std::cos(phi * M_PI / 180), s = std::sin(phi * M_PI / 180);
  for (int k = 0; k < n; ++k) {
    const double x = 190 + 0.37 * k - std::floor(0.37 * k), y = 160 + 0.61 * k - std::floor(0.61 * k);
    tracker->request_reacquire();
    PoseEstimate e;
    for (int f = 0; f < 3; ++f) {
      scene.render(cx, cy, x, y, phi, fw, fh, field, dose, 100 + static_cast<std::uint64_t>(k * 7 + f));
      hal::FrameMeta meta;
      meta.roi = tracker->next_roi();
      meta.field_w = fw;
      meta.field_h = fh;
      meta.bits = 16;
      crop(field, fw, meta.roi, roi);
      e = tracker->update(pipeline::to_pose_frame(meta, roi.data()));
    }
    char tag[64];
    std::snprintf(tag, sizeof tag, "warp phi%g dose%g k%d", phi, dose, k);
    dump_pose(tag, e);
    const double ex = e.x_px - x, ey = e.y_px - y;
    // Into the target's frame: its +x axis is (cos φ, −sin φ) on screen (CCW with y down).
    b.along += ex * c - ey * s;
    b.across += ex * s + ey * c;
    b.phi += angle_error(e.phi_deg, phi);
    b.rms_px += ex * ex + ey * ey;
    b.rms_deg += angle_error(e.phi_deg, phi) * angle_error(e.phi_deg, phi);
  }
  b.along /= n;
  b.across /= n;
  b.phi /= n;
  b.rms_px = std::sqrt(b.rms_px / n);
  b.rms_deg = std::sqrt(b.rms_deg / n);
  return b;
}

// The bound for warp_bias's frames (Poisson at dose), averaged over a few of its sub-pixel phases.
CrlbMean warp_bound(const config::TrackerConfig& tc, double phi, double dose) {
  static const WarpScene scene = WarpScene::load(std::string(SEMPOSE_TEST_DATA) + "/sem/lamella_on_post_eb.pgm", 1.0);
  const std::int64_t t0 = rt::now_ns();
  CrlbMean m;
  for (int k = 0; k < 12; k += 4) {
    const double x = 190 + 0.37 * k - std::floor(0.37 * k), y = 160 + 0.61 * k - std::floor(0.61 * k);
    m.add(crlb_warp(scene, 563.5, 527.5, tc, x, y, phi, dose));
  }
  g_bound_s += (rt::now_ns() - t0) * 1e-9;
  return m;
}

Bias sim_bias(const config::TrackerConfig& tc, const std::string& target, double phi, bool background) {
  Bias b;
  const double c = std::cos(phi * M_PI / 180), s = std::sin(phi * M_PI / 180);
  const int n = 6;
  for (int k = 0; k < n; ++k) {
    Scenario sc;
    sc.target = target;
    sc.motion = "static";
    sc.noise = false;
    sc.drift = false;
    sc.background = background;
    sc.frames = 3;
    sc.start_x_px = 320 + k / 6.0;
    sc.start_y_px = 240 + k / 6.0;
    sc.start_phi_deg = phi;
    SimHarness h(sc, tc);
    h.run();
    const auto& e = h.poses().back();
    const auto& tr = h.truth().back();
    char tag[96];
    std::snprintf(tag, sizeof tag, "simbias %s phi%g bg%d k%d", target.c_str(), phi, background, k);
    dump_pose(tag, e);
    const double ex = e.x_px - tr.x_px, ey = e.y_px - tr.y_px;
    b.along += ex * c - ey * s;
    b.across += ex * s + ey * c;
    b.phi += angle_error(e.phi_deg, tr.phi_deg);
    b.rms_px += ex * ex + ey * ey;
    b.rms_deg += angle_error(e.phi_deg, tr.phi_deg) * angle_error(e.phi_deg, tr.phi_deg);
  }
  b.along /= n;
  b.across /= n;
  b.phi /= n;
  b.rms_px = std::sqrt(b.rms_px / n);
  b.rms_deg = std::sqrt(b.rms_deg / n);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  const bool bias_only = argc > 1 && std::strcmp(argv[1], "--bias") == 0;
  // --only TARGET [MOTION]: just those table rows, no bias section (a quick look at one case).
  const bool only = argc > 2 && std::strcmp(argv[1], "--only") == 0;
  const std::string only_target = only ? argv[2] : "";
  const std::string only_motion = only && argc > 3 ? argv[3] : "";
  config::TrackerConfig tc;
  if (const char* dump = std::getenv("POSE_DUMP")) g_dump = std::fopen(dump, "w");
  const int frames = quick ? 60 : 150;
  const std::int64_t bench_t0 = rt::now_ns();
  std::printf("accuracy on the simulated SEM: 640x480 field, pattern %d², ROI %d², 250 ns dwell, %d frames per run\n"
              "targets: needle_tip = needle_contact_eb.pgm crop 552,430 120x160 at 90x120 (threshold mask);\n"
              "         lamella_post = lamella_on_post_eb.pgm crop 420,460 180x180 at 100x100; lamella = procedural 100x64\n"
              "false = TRACKING poses > 3 px off the truth; recov = frames from a jump to a pose < 1 px off\n"
              "crlb_px, crlb_deg = Cramér–Rao bound of one frame (2-D position RMS, angle SD) at the run's true poses\n"
              "  (every 15th frame): Poisson × Gamma gain + read noise over the tracker's mask; eff = crlb_px / rms_px\n",
              tc.pattern_size_px, tc.roi_size_px, frames);
  std::printf("%-12s %-6s %5s | %8s %6s %7s %7s %7s %7s %5s %5s | %7s %8s %5s\n", "target", "motion", "dose", "tracked",
              "search", "rms_px", "max_px", "rms_deg", "max_deg", "recov", "false", "crlb_px", "crlb_deg", "eff");
  int bad = 0;
  for (const char* target : {"needle_tip", "lamella_post", "lamella"}) {
    if (bias_only) break;
    if (only && only_target != target) continue;
    for (const char* motion : {"smooth", "fast", "spin", "jump"}) {
      if (only && !only_motion.empty() && only_motion != motion) continue;
      for (double dose : {20.0, 6.0, 2.5, 1.0}) {
        if (quick && dose == 20.0) continue;
        Scenario s;
        s.target = target;
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
        // TRACE_DOSE=<dose> in the environment: every frame's pose and truth of that dose's runs.
        if (std::getenv("TRACE_DOSE") && std::atof(std::getenv("TRACE_DOSE")) == dose)
          for (std::size_t f = 0; f < h.poses().size(); ++f) {
            const auto& e = h.poses()[f];
            const auto& t = h.truth()[f];
            std::printf("f%3zu st%d s%d rb%02x est %7.2f %7.2f %7.2f truth %7.2f %7.2f %7.2f sc %.3f\n", f,
                        static_cast<int>(e.state), e.searched, e.reason_bits, e.x_px, e.y_px, e.phi_deg, t.x_px,
                        t.y_px, t.phi_deg, e.score);
          }
        for (std::size_t f = 0; f < h.poses().size(); ++f) {
          char tag[96];
          std::snprintf(tag, sizeof tag, "run %s %s %g f%zu", target, motion, dose, f);
          dump_pose(tag, h.poses()[f]);
        }
        for (const auto& e : h.poses())
          if (!std::isfinite(e.x_px) || !std::isfinite(e.phi_deg) || !std::isfinite(e.score)) ++bad;
        char recov[16] = "-";
        if (r.jumps) std::snprintf(recov, sizeof recov, "%d", r.recovery_max);
        const CrlbMean bound = run_bound(s, tc, h.truth());
        const std::string eff = r.err_n ? fmt(bound.pos_rms_px() / r.rms_px(), "%.2f") : "-";
        std::printf("%-12s %-6s %5.1f | %7.1f%% %6d %7.3f %7.3f %7.3f %7.3f %5s %5d | %7s %8s %5s\n", target, motion,
                    dose, 100.0 * r.tracked_share(), r.searches, r.rms_px(), r.max_px, r.rms_deg(), r.max_deg, recov,
                    r.false_tracking, fmt(bound.pos_rms_px()).c_str(), fmt(bound.phi_deg()).c_str(), eff.c_str());
        std::fflush(stdout);
      }
    }
  }

  if (only) {
    std::printf("(bounds computed in %.2f s of %.1f s)\n", g_bound_s, (rt::now_ns() - bench_t0) * 1e-9);
    return bad ? 2 : 0;
  }
  std::printf("\nbias (mean error in the target's own frame: along its x axis, across it, and in angle)\n");
  std::printf("(rms_deg: RMS angle error; crlb_px, crlb_deg, eff: the single-frame bound, Poisson, as in the table above)\n");
  std::printf("%-36s %6s | %8s %8s %8s %8s %8s | %7s %8s %5s\n", "source", "phi", "along", "across", "phi_deg", "rms_px",
              "rms_deg", "crlb_px", "crlb_deg", "eff");
  for (double phi : {0.0, 90.0, 180.0, -90.0, 33.0}) {
    if (bias_only) break;
    const Bias b = warp_bias(tc, phi, 0, quick ? 6 : 12);
    std::printf("%-36s %6.0f | %+8.4f %+8.4f %+8.4f %8.4f %8.4f |\n", "warped real SEM, noise-free", phi, b.along, b.across,
                b.phi, b.rms_px, b.rms_deg);
  }
  for (double phi : {0.0, 90.0, 180.0, -90.0}) {
    const Bias b = warp_bias(tc, phi, 6.0, quick ? 12 : 32);
    const CrlbMean bound = warp_bound(tc, phi, 6.0);
    std::printf("%-36s %6.0f | %+8.4f %+8.4f %+8.4f %8.4f %8.4f | %7s %8s %5s\n", "warped real SEM, dose 6 (Poisson)", phi,
                b.along, b.across, b.phi, b.rms_px, b.rms_deg, fmt(bound.pos_rms_px()).c_str(),
                fmt(bound.phi_deg()).c_str(), fmt(bound.pos_rms_px() / b.rms_px, "%.2f").c_str());
  }
  for (const char* target : {"needle_tip", "lamella_post"}) {
    for (double phi : {0.0, 90.0, 180.0, -90.0}) {
      const Bias b = sim_bias(tc, target, phi, true);
      char name[64];
      std::snprintf(name, sizeof name, "simulator %s, noise-free", target);
      std::printf("%-36s %6.0f | %+8.4f %+8.4f %+8.4f %8.4f %8.4f |\n", name, phi, b.along, b.across, b.phi, b.rms_px,
                  b.rms_deg);
    }
    for (double phi : {0.0, 180.0}) {
      // The same with a flat background: the static clutter under the pattern's rim is what
      // drags the peak (it stays put while the target moves and turns).
      const Bias b = sim_bias(tc, target, phi, false);
      char name[64];
      std::snprintf(name, sizeof name, "  same, flat background");
      std::printf("%-36s %6.0f | %+8.4f %+8.4f %+8.4f %8.4f %8.4f |\n", name, phi, b.along, b.across, b.phi, b.rms_px,
                  b.rms_deg);
    }
  }
  // Peak-fit bias against the sub-pixel phase (noise off): the joint fit vs. phase.
  std::printf("\npeak-fit error vs sub-pixel phase (simulator lamella_post, noise off, x = 320 + f, y = 240 + f):\n");
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
      s.drift = false;
      s.frames = 3;
      s.start_x_px = 320 + k / 10.0;
      s.start_y_px = 240 + k / 10.0;
      SimHarness h(s, t2);
      h.run();
      const auto& e = h.poses().back();
      const auto& tr = h.truth().back();
      char tag[64];
      std::snprintf(tag, sizeof tag, "phase %s k%d", fit, k);
      dump_pose(tag, e);
      const double ex = e.x_px - tr.x_px;
      std::printf(" f=%.1f:%+.3f", k / 10.0, ex);
      worst = std::max(worst, std::fabs(ex));
      sum2 += ex * ex;
      ++n;
    }
    std::printf("  | max %.3f px rms %.3f px\n", worst, std::sqrt(sum2 / n));
  }
  std::printf("\n(bounds computed in %.2f s of %.1f s)\n", g_bound_s, (rt::now_ns() - bench_t0) * 1e-9);
  return bad ? 2 : 0;
}
