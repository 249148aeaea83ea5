// The simulator's time-varying effects, each against what it must do physically: a scale
// trajectory renders the target that much larger, the gripper's jaws open while its body
// stays, charging moves the mean brightness with its steps and ramps, defocus widens an edge
// by the configured σ, the detector's low-pass has a first-order step response that depends
// on the dwell. With every effect off the frames are bit for bit those of the simulator
// before the effects existed; SimScene::render_mean is the source's own noise-free render.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "sempose/config/reader.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/sim_source.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "test_util.hpp"

namespace sempose::hal {
namespace {

constexpr std::int64_t kT0 = SimSource::kVirtualEpochNs;

ScanLimits limits(int w, int h, int bits = 16) {
  ScanLimits lim;
  lim.field_w = w;
  lim.field_h = h;
  lim.max_roi_w = w;
  lim.max_roi_h = h;
  lim.bits = bits;
  return lim;
}

// Output counts of scene brightness b (16 bit, mean gain), as the detector maps them.
double counts_of(const config::SimConfig& c, double b) { return c.output_offset * 65535.0 + 0.5 + b * c.output_white * 65535.0; }

// A field-sized background image: dark (0) left of column edge_x, level/255 from it on.
std::string step_background(int w, int h, int edge_x, int level) {
  const auto path = (test::temp_dir("effects") / "step.pgm").string();
  Image img;
  img.width = w;
  img.height = h;
  img.bits = 8;
  img.pixels.resize(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.pixels[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint16_t>(x >= edge_x ? level : 0);
  write_pgm(path, img);
  return path;
}

config::SimConfig step_config(int w, int h, int edge_x) {
  config::SimConfig c = test::clean_config();
  c.background.source = "image";
  c.background.path = step_background(w, h, edge_x, 200);
  return c;
}

std::vector<Pixel> render(SimSource& src, const Roi& roi, std::uint32_t dwell, std::int64_t t, TargetTruth* truth = nullptr) {
  std::vector<Pixel> px(static_cast<std::size_t>(roi.w) * roi.h);
  TargetTruth tr[kMaxTargets];
  src.render(roi, dwell, t, 0, px.data(), truth ? truth : tr);
  return px;
}

// A procedural target on a black field, no noise and no PSF: geometry only.
config::SimConfig one_target(const std::string& kind, int w, int h, double x, double y) {
  config::SimConfig c = test::clean_config();
  config::SimTargetConfig t;
  t.texture.source = kind;
  t.width_px = w, t.height_px = h;
  t.x_px = x, t.y_px = y;
  c.targets = {t};
  return c;
}

// With every new effect at its default the frames must not move: a hash of frames rendered
// by the simulator as it was before the effects (commit e201f1f; two moving procedural
// targets, noise, jitter, drift, beam lag, 8 and 16 bit, four dwells).
TEST(SimEffects, EffectsOffRendersBitForBitAsBefore) {
  ScanLimits lim = limits(320, 240, 8);
  lim.max_roi_w = lim.max_roi_h = 128;
  config::SimConfig c;
  c.clock = "virtual";
  c.targets.clear();
  config::SimTargetConfig a;
  a.texture.source = "lamella";
  a.width_px = 60, a.height_px = 30, a.x_px = 100, a.y_px = 100;
  a.trajectory.kind = "sine";
  a.trajectory.amplitude_x_px = 20, a.trajectory.amplitude_y_px = 10, a.trajectory.amplitude_phi_deg = 15;
  a.trajectory.period_s = 0.05;
  config::SimTargetConfig b;
  b.texture.source = "gripper";
  b.width_px = 80, b.height_px = 60, b.x_px = 140, b.y_px = 120, b.phi_deg = 30;
  b.trajectory.kind = "spin";
  b.trajectory.omega_deg_s = 900;
  c.targets = {a, b};
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a over every pixel
  for (int bits : {8, 16}) {
    lim.bits = bits;
    SimSource src(lim, c);
    std::vector<Pixel> px(128 * 128);
    TargetTruth truth[kMaxTargets];
    for (int f = 0; f < 4; ++f) {
      src.render({40 + 10 * f, 50, 128, 120}, 100 + 150 * f, kT0 + f * 7'000'000, f, px.data(), truth);
      for (int i = 0; i < 128 * 120; ++i) {
        h ^= px[static_cast<std::size_t>(i)];
        h *= 1099511628211ull;
      }
    }
  }
  EXPECT_EQ(h, 0xf54e55ebce2e66a5ull);
}

TEST(SimEffects, ScaleTrajectoryRendersTheTargetThatMuchLarger) {
  const ScanLimits lim = limits(320, 240);
  config::SimConfig c = one_target("lamella", 80, 40, 160, 120);
  c.targets[0].scale.from = 1.0;
  c.targets[0].scale.to = 1.25;
  c.targets[0].scale.start_s = 0.0;
  c.targets[0].scale.ramp_s = 1.0;
  SimSource src(lim, c);
  // Footprint: the bounding box of the pixels brighter than 0.05 (the lamella's surface is
  // ≥ 0.5): a w×h target spans w·scale + 1 columns (bilinear edges reach half a pixel out).
  auto extent = [&](std::int64_t t, TargetTruth* truth, int& w, int& h) {
    const std::vector<Pixel> px = render(src, {0, 0, 320, 240}, 100, t, truth);
    int x0 = 320, x1 = -1, y0 = 240, y1 = -1;
    for (int y = 0; y < 240; ++y)
      for (int x = 0; x < 320; ++x)
        if (px[static_cast<std::size_t>(y) * 320 + x] > counts_of(c, 0.05)) {
          x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
    w = x1 - x0 + 1;
    h = y1 - y0 + 1;
  };
  TargetTruth t0[kMaxTargets], t_half[kMaxTargets], t_end[kMaxTargets];
  int w0, h0, w_half, h_half, w_end, h_end;
  extent(kT0, t0, w0, h0);
  extent(kT0 + 500'000'000 - lim.scan_time_ns(320, 240, 100) / 2, t_half, w_half, h_half);
  extent(kT0 + 2'000'000'000, t_end, w_end, h_end);
  std::printf("footprint %dx%d px at scale 1, %dx%d at 1.125, %dx%d at 1.25\n", w0, h0, w_half, h_half, w_end, h_end);
  EXPECT_NEAR(w0, 81, 1);
  EXPECT_NEAR(h0, 41, 1);
  EXPECT_NEAR(w_half, 80 * 1.125 + 1, 1);
  EXPECT_NEAR(h_half, 40 * 1.125 + 1, 1);
  EXPECT_NEAR(w_end, 80 * 1.25 + 1, 1);
  EXPECT_NEAR(h_end, 40 * 1.25 + 1, 1);
  EXPECT_NEAR(t0[0].scale, 1.0, 0.01);
  EXPECT_NEAR(t_half[0].scale, 1.125, 1e-6);
  EXPECT_EQ(t_end[0].scale, 1.25);
  EXPECT_EQ(t_end[0].x_px, 160);  // about the pose point: it does not move
}

TEST(SimEffects, GripperJawsOpenWhileTheBodyStays) {
  const ScanLimits lim = limits(320, 240);
  config::SimConfig c = one_target("gripper", 160, 120, 160, 120);
  c.psf_sigma_px = 0.8;
  c.targets[0].jaws.from = 0;
  c.targets[0].jaws.to = 8;
  c.targets[0].jaws.ramp_s = 1.0;
  SimSource src(lim, c);
  const double left = 160 - 79.5, top = 120 - 59.5;
  // First and last row brighter than half the gripper in column x: its top and bottom edges.
  auto edges = [&](const std::vector<Pixel>& px, int x, int& first, int& last) {
    first = last = -1;
    for (int y = 0; y < 240; ++y)
      if (px[static_cast<std::size_t>(y) * 320 + x] > counts_of(c, 0.3)) {
        if (first < 0) first = y;
        last = y;
      }
  };
  TargetTruth shut[kMaxTargets], open[kMaxTargets];
  const std::vector<Pixel> a = render(src, {0, 0, 320, 240}, 100, kT0, shut);
  const std::vector<Pixel> b = render(src, {0, 0, 320, 240}, 100, kT0 + 2'000'000'000, open);
  const int jaw_x = static_cast<int>(left + 0.8 * 160), body_x = static_cast<int>(left + 0.2 * 160);
  int jt0, jb0, jt1, jb1, bt0, bb0, bt1, bb1;
  edges(a, jaw_x, jt0, jb0);
  edges(b, jaw_x, jt1, jb1);
  edges(a, body_x, bt0, bb0);
  edges(b, body_x, bt1, bb1);
  EXPECT_NEAR(jt0, top + 0.12 * 120, 1.5);  // the upper jaw's top edge at rest
  EXPECT_EQ(jt0 - jt1, 8);                  // opened 8 px up
  EXPECT_EQ(jb1 - jb0, 8);                  // the lower jaw 8 px down
  EXPECT_EQ(bt0, bt1);                      // the body does not move
  EXPECT_EQ(bb0, bb1);
  for (int y = 0; y < 240; ++y) EXPECT_EQ(a[static_cast<std::size_t>(y) * 320 + body_x], b[static_cast<std::size_t>(y) * 320 + body_x]);
  EXPECT_EQ(shut[0].x_px, open[0].x_px);  // the pose point is the body's
  EXPECT_EQ(shut[0].y_px, open[0].y_px);
}

// The rigid-only shape mask (the bench's --mask body): no pixel in it changes at any jaw
// opening the profile reaches, and it keeps the body (not only a sliver). The whole outline
// does hold pixels the jaws change — the mask the rigid option must not give.
TEST(SimEffects, RigidOnlyMaskHoldsNoPixelTheJawsChange) {
  const ScanLimits lim = limits(320, 240);
  config::SimConfig c = one_target("gripper", 110, 84, 160.5, 120.5);
  c.psf_sigma_px = 0.8;
  c.targets[0].jaws.amplitude = 8, c.targets[0].jaws.period_s = 0.4;  // the bench's jaws rows
  const int n = 128;
  const Image rigid = render_sim_pattern_mask(c, lim, 0, n, true);
  const Image outline = render_sim_pattern_mask(c, lim, 0, n);
  // The crop's pixel (x, y) is field pixel (97 + x, 57 + y): the target at rest in its centre.
  const Roi roi{97, 57, n, n};
  const SimScene scene(c, lim);
  auto mean_at = [&](double jaw) {
    SimTargetPose pose{true, 160.5, 120.5, 0.0, 1.0, jaw};
    std::vector<float> mean;
    scene.render_mean(roi, &pose, 1.0, 0.0, 0.0, mean, nullptr);
    return mean;
  };
  const std::vector<float> shut = mean_at(0);
  std::vector<std::uint8_t> changes(shut.size(), 0);
  for (double jaw : {-8.0, -4.0, 4.0, 8.0}) {
    const std::vector<float> m = mean_at(jaw);
    for (std::size_t i = 0; i < m.size(); ++i) changes[i] |= std::fabs(m[i] - shut[i]) > 1e-4f;
  }
  int rigid_n = 0, outline_n = 0, rigid_changing = 0, outline_changing = 0;
  for (std::size_t i = 0; i < shut.size(); ++i) {
    rigid_n += rigid.pixels[i] != 0;
    outline_n += outline.pixels[i] != 0;
    rigid_changing += rigid.pixels[i] != 0 && changes[i];
    outline_changing += outline.pixels[i] != 0 && changes[i];
  }
  EXPECT_EQ(rigid_changing, 0);
  EXPECT_GT(outline_changing, 500);  // the jaws' edges: what the rigid mask leaves out
  // The body is 45 % of the 110 px width at 84 % of the 84 px height (~3500 px); the mask keeps
  // it less what the jaws reach, plus its blurred rim against the background.
  EXPECT_GT(rigid_n, 2500);
  EXPECT_LT(rigid_n, outline_n);
}

TEST(SimEffects, ChargingStepsAndRampsMoveTheMeanBrightness) {
  const ScanLimits lim = limits(256, 256);
  config::SimConfig c = test::clean_config();
  c.background.mean = 0.4;
  c.noise = true;
  c.output_white = 0.5;  // room above for the brighter state
  c.charging_gain.from = 1.0, c.charging_gain.to = 1.35, c.charging_gain.start_s = 0.5;  // a step
  c.charging_offset.from = 0.0, c.charging_offset.to = 0.05, c.charging_offset.start_s = 0.5;
  SimSource src(lim, c);
  auto mean = [](const std::vector<Pixel>& px) {
    double s = 0;
    for (Pixel p : px) s += p;
    return s / px.size();
  };
  const double before = mean(render(src, {0, 0, 256, 256}, 250, kT0 + 100'000'000));
  const double after = mean(render(src, {0, 0, 256, 256}, 250, kT0 + 1'000'000'000));
  EXPECT_NEAR(before, counts_of(c, 0.4), 0.01 * counts_of(c, 0.4));
  EXPECT_NEAR(after, counts_of(c, 1.35 * 0.4 + 0.05), 0.01 * counts_of(c, 1.35 * 0.4 + 0.05));
  // A ramp within one frame: each line follows the gain at its own scan time.
  config::SimConfig r = test::clean_config();
  r.background.mean = 0.4;
  r.output_white = 0.5;
  r.charging_gain.from = 1.0, r.charging_gain.to = 1.5, r.charging_gain.ramp_s = 0.01;
  SimSource ramp(lim, r);
  const std::vector<Pixel> px = render(ramp, {0, 0, 256, 256}, 100, kT0);
  const double line_s = (256 * 100 + lim.line_flyback_ns) * 1e-9;
  for (int row : {0, 100, 255}) {
    const double t = row * line_s + 0.5 * 256 * 100e-9;
    const double g = 1.0 + 0.5 * std::min(1.0, t / 0.01);
    EXPECT_NEAR(px[static_cast<std::size_t>(row) * 256 + 17], counts_of(r, g * 0.4), 1.0) << row;
  }
}

TEST(SimEffects, DefocusWidensAnEdgeByItsSigma) {
  const ScanLimits lim = limits(128, 64);
  config::SimConfig c = step_config(128, 64, 64);
  c.defocus_px.from = 0.0, c.defocus_px.to = 2.0, c.defocus_px.start_s = 0.5;
  SimSource src(lim, c);
  // Edge width: the variance of the profile's derivative along a line is σ² for a Gaussian PSF.
  auto edge_sigma = [&](const std::vector<Pixel>& px, int row) {
    double s0 = 0, s1 = 0, s2 = 0;
    for (int x = 1; x < 128; ++x) {
      const double d = static_cast<double>(px[static_cast<std::size_t>(row) * 128 + x]) - px[static_cast<std::size_t>(row) * 128 + x - 1];
      const double xc = x - 0.5;
      s0 += d, s1 += d * xc, s2 += d * xc * xc;
    }
    const double m = s1 / s0;
    return std::sqrt(std::max(0.0, s2 / s0 - m * m));
  };
  const std::vector<Pixel> sharp = render(src, {0, 0, 128, 64}, 100, kT0);
  const std::vector<Pixel> blurred = render(src, {0, 0, 128, 64}, 100, kT0 + 1'000'000'000);
  EXPECT_LT(edge_sigma(sharp, 32), 0.1);
  EXPECT_NEAR(edge_sigma(blurred, 32), 2.0, 0.1);
  EXPECT_NEAR(edge_sigma(blurred, 0), 2.0, 0.1);  // also on the ROI's first line (the margin is rendered)
  // A ROI sees the same blurred scene as the full field (the margin comes from outside it).
  const std::vector<Pixel> roi = render(src, {40, 10, 48, 20}, 100, kT0 + 1'000'000'000);
  for (int x = 0; x < 48; ++x) EXPECT_NEAR(roi[static_cast<std::size_t>(5) * 48 + x], blurred[static_cast<std::size_t>(15) * 128 + 40 + x], 1.0);
}

TEST(SimEffects, DetectorLowPassHasAFirstOrderStepResponseSetByTheDwell) {
  const ScanLimits lim = limits(64, 8);
  for (std::uint32_t dwell : {100u, 250u}) {
    config::SimConfig c = step_config(64, 8, 32);
    c.detector_tau_ns = 75;
    SimSource src(lim, c);
    const std::vector<Pixel> px = render(src, {0, 0, 64, 8}, dwell, kT0);
    const double lo = counts_of(c, 0.0), hi = counts_of(c, 200.0 / 255.0);
    const double keep = std::exp(-static_cast<double>(dwell) / 75.0);  // 1 − a
    double lag_px = 0;
    for (int i = 32; i < 64; ++i) {
      const double expect = lo + (hi - lo) * (1.0 - std::pow(keep, i - 31));
      EXPECT_NEAR(px[static_cast<std::size_t>(3) * 64 + i], expect, 1.0) << "dwell " << dwell << " px " << i;
      lag_px += (hi - px[static_cast<std::size_t>(3) * 64 + i]) / (hi - lo);
    }
    // The edge's delay in pixels: (1 − a)/a for a first-order filter sampled once per dwell.
    EXPECT_NEAR(lag_px, keep / (1 - keep), 0.05) << dwell;
    std::printf("detector tau 75 ns at %u ns dwell: an edge lags %.2f px\n", dwell, lag_px);
    EXPECT_NEAR(px[static_cast<std::size_t>(3) * 64 + 31], lo, 1.0);  // nothing before the edge
  }
}

TEST(SimEffects, RenderMeanIsTheSourcesNoiseFreeRender) {
  const ScanLimits lim = limits(320, 240);
  config::SimConfig c = one_target("gripper", 120, 90, 150.3, 118.6);
  c.psf_sigma_px = 0.8;
  c.background.mean = 0.3;
  c.background.contrast = 0.12;
  c.targets[0].phi_deg = -37.0;
  c.targets[0].scale = config::TimeProfile::constant(1.2);
  c.targets[0].jaws = config::TimeProfile::constant(5.0);
  c.charging_gain = config::TimeProfile::constant(1.3);
  c.charging_offset = config::TimeProfile::constant(0.05);
  c.defocus_px = config::TimeProfile::constant(1.5);
  c.output_white = 0.5;  // 1.3·b + 0.05 stays below saturation
  SimSource src(lim, c);
  const Roi roi{60, 40, 180, 150};
  const std::vector<Pixel> px = render(src, roi, 250, kT0);
  const SimTargetPose pose = src.target_pose(0, 0.0);
  EXPECT_EQ(pose.scale, 1.2);
  EXPECT_EQ(pose.jaw_open_px, 5.0);
  std::vector<float> mean, cover;
  src.scene().render_mean(roi, &pose, 1.3, 0.05, 1.5, mean, &cover);
  double worst = 0, spread = 0;
  int covered = 0;
  for (std::size_t i = 0; i < px.size(); ++i) {
    worst = std::max(worst, std::fabs(px[i] - std::floor(counts_of(c, mean[i]))));
    spread = std::max(spread, static_cast<double>(std::fabs(mean[i] - mean[0])));
    covered += cover[i] > 0.5f;
  }
  EXPECT_LE(worst, 1.0);
  EXPECT_GT(spread, 0.3);  // the ROI shows the target (not a blank comparison)
  EXPECT_GT(covered, 0.5 * 1.2 * 1.2 * 120 * 90);
}

TEST(SimEffects, NoAllocationWithEveryEffectOn) {
  const ScanLimits lim = limits(320, 240, 8);
  config::SimConfig c = one_target("gripper", 120, 90, 160, 120);
  c.noise = true;
  c.targets[0].trajectory.kind = "spin";
  c.targets[0].trajectory.omega_deg_s = 200;
  c.targets[0].scale.to = 1.3, c.targets[0].scale.from = 1.0, c.targets[0].scale.ramp_s = 0.1;
  c.targets[0].jaws.amplitude = 6, c.targets[0].jaws.period_s = 0.05;
  c.charging_gain.amplitude = 0.2, c.charging_gain.period_s = 0.03;
  c.defocus_px.from = 0.0, c.defocus_px.to = 3.0, c.defocus_px.ramp_s = 0.05;
  c.detector_tau_ns = 75;
  SimSource src(lim, c);
  FramePool pool(2, 320 * 240);
  std::uint64_t allocs = 0;
  {
    rt::alloc::ScopedArm arm;
    for (int f = 0; f < 60; ++f) {
      const Roi roi = f % 20 == 0 ? Roi{0, 0, 320, 240} : Roi{(f * 7) % 192, (f * 3) % 112, 128, 128};
      if (src.start({roi, 100u + 50u * static_cast<std::uint32_t>(f % 4), 0}, pool[f % 2]) != StartResult::kStarted) break;
      while (src.poll() != PollResult::kDone) {
      }
      src.advance_virtual_ns(1'000'000);
    }
    allocs = rt::alloc::this_thread_allocations();
  }
  EXPECT_EQ(allocs, 0u);
  EXPECT_EQ(pool[1].meta.seq, 59u);
}

TEST(SimEffects, ConfigReadsTheEffectsAndNamesBadValues) {
  const auto path = (test::temp_dir("effects_cfg") / "c.yaml").string();
  auto read = [&](const std::string& yaml, config::SimConfig& sim) {
    std::ofstream(path) << yaml;
    config::Errors errors(path);
    YAML::Node root = config::load_file(path, errors);
    {
      config::Section top(root, "", errors);
      config::Section s = top.child("sim");
      config::read_sim(s, sim);
    }
    return errors.joined();
  };
  config::SimConfig sim;
  EXPECT_EQ(read(R"(
sim:
  detector_tau_ns: 75
  charging: {gain: {from: 1, to: 1.35, start_s: 2, ramp_s: 0.5}, offset: {value: 0.02, amplitude: 0.01, period_s: 3}}
  defocus_px: {from: 0, to: 1.5, start_s: 1, ramp_s: 4}
  targets:
    - texture: {source: gripper}
      scale: {from: 1, to: 1.25, ramp_s: 10}
      jaws: {amplitude: 8, period_s: 2}
)",
                 sim),
            "");
  EXPECT_EQ(sim.detector_tau_ns, 75);
  EXPECT_EQ(sim.charging_gain.to, 1.35);
  EXPECT_EQ(sim.charging_gain.start_s, 2);
  EXPECT_EQ(sim.charging_offset.from, 0.02);
  EXPECT_EQ(sim.charging_offset.to, 0.02);
  EXPECT_EQ(sim.charging_offset.amplitude, 0.01);
  EXPECT_EQ(sim.defocus_px.to, 1.5);
  ASSERT_EQ(sim.targets.size(), 1u);
  EXPECT_EQ(sim.targets[0].scale.to, 1.25);
  EXPECT_EQ(sim.targets[0].jaws.amplitude, 8);
  EXPECT_DOUBLE_EQ(sim.targets[0].scale.at(5.0), 1.125);
  // Defaults: every effect off.
  const config::SimConfig d;
  EXPECT_EQ(d.detector_tau_ns, 0);
  EXPECT_TRUE(d.charging_gain.is_constant() && d.charging_gain.from == 1.0);
  EXPECT_TRUE(d.defocus_px.is_constant() && d.defocus_px.from == 0.0);
  EXPECT_TRUE(d.targets[0].scale.is_constant() && d.targets[0].scale.from == 1.0);
  config::SimConfig bad;
  const std::string err = read(R"(
sim:
  detector_tau_ns: -5
  defocus_px: {from: 0, to: 12}
  charging: {gain: {from: 1, amplitude: 20}}
  targets:
    - texture: {source: lamella}
      jaws: {to: 5}
      scale: {to: 0.1, ramp: 3}
)",
                               bad);
  for (const char* expected : {"sim.detector_tau_ns: -5 is outside", "sim.defocus_px.to: 12 is outside",
                               "sim.charging.gain.amplitude", "sim.targets[0].jaws: jaws move only on a procedural gripper",
                               "sim.targets[0].scale.to: 0.1 is outside", "sim.targets[0].scale.ramp: unknown key"}) {
    EXPECT_NE(err.find(expected), std::string::npos) << expected << "\n" << err;
  }
}

}  // namespace
}  // namespace sempose::hal
