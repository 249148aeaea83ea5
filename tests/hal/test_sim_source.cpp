// The ScanSource contract of the simulator: timing model and both clocks, request checks,
// metadata, determinism, and no allocation in start()/poll().
#include <gtest/gtest.h>

#include <vector>

#include "sempose/hal/sim_source.hpp"
#include "sempose/hal/trajectory.hpp"
#include "sempose/hal/source_factory.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"
#include "test_util.hpp"

namespace sempose::hal {
namespace {

ScanLimits small_limits() {
  ScanLimits lim;
  lim.field_w = 320;
  lim.field_h = 240;
  lim.max_roi_w = lim.max_roi_h = 128;
  return lim;
}

// Procedural targets only (no files): a lamella on a random walk and a spinning gripper.
config::SimConfig moving_config(const std::string& clock) {
  config::SimConfig c;
  c.clock = clock;
  c.targets.clear();
  config::SimTargetConfig a;
  a.texture.source = "lamella";
  a.width_px = 60, a.height_px = 30;
  a.x_px = 100, a.y_px = 100;
  a.trajectory.kind = "random_walk";
  a.trajectory.sigma_px_per_sqrt_s = 50;
  a.trajectory.margin_px = 40;
  config::SimTargetConfig b;
  b.texture.source = "gripper";
  b.width_px = 80, b.height_px = 60;
  b.x_px = 220, b.y_px = 150;
  b.trajectory.kind = "spin";
  b.trajectory.omega_deg_s = 90;
  c.targets = {a, b};
  return c;
}

// The random walk's pose at t is the same whatever was asked before: forward, back a little
// (every frame goes back from its last line to mid-scan; that replayed the walk from t = 0 each
// frame, found probing: recordings O(frames²), a run's acquisition slower every second), back
// beyond the kept checkpoints, and forward again.
TEST(Trajectory, RandomWalkIsAFunctionOfTimeWhateverTheOrderOfQuestions) {
  config::TrajectoryConfig c;
  c.kind = "random_walk";
  c.knot_s = 1e-4;
  c.sigma_px_per_sqrt_s = 50;
  c.sigma_deg_per_sqrt_s = 20;
  c.margin_px = 10;
  auto fresh = [&](double t) { return Trajectory(c, {160, 120, 0}, 320, 240, 7).at(t); };
  Trajectory walk(c, {160, 120, 0}, 320, 240, 7);
  const double times[] = {0.0, 0.04, 0.02, 0.08, 0.06, 0.12, 3.0, 2.99, 2.5, 0.013, 3.5, 1e-5, 3.5};
  for (const double t : times) {
    const Pose2 got = walk.at(t), want = fresh(t);
    EXPECT_EQ(got.x_px, want.x_px) << t;
    EXPECT_EQ(got.y_px, want.y_px) << t;
    EXPECT_EQ(got.phi_deg, want.phi_deg) << t;
  }
}

TEST(SimSource, VirtualClockFollowsTheScanTimeModel) {
  const ScanLimits lim = small_limits();
  SimSource src(lim, moving_config("virtual"));
  FramePool pool(1, 128 * 128);
  EXPECT_TRUE(src.is_virtual_time());
  EXPECT_EQ(src.poll(), PollResult::kIdle);
  const std::int64_t t0 = src.now_ns();
  ASSERT_EQ(src.start({{10, 20, 128, 96}, 250, 1}, pool[0]), StartResult::kStarted);
  EXPECT_EQ(src.start({{10, 20, 128, 96}, 250, 1}, pool[0]), StartResult::kBusy);
  const std::int64_t expected = 128LL * 96 * 250 + 96LL * lim.line_flyback_ns;
  EXPECT_EQ(src.expected_done_ns(), t0 + expected);
  EXPECT_EQ(src.poll(), PollResult::kDone);
  EXPECT_EQ(src.now_ns(), t0 + expected);
  const FrameMeta& m = pool[0].meta;
  EXPECT_EQ(m.t_scan_start_ns, t0);
  EXPECT_EQ(m.t_scan_end_ns, t0 + expected);
  EXPECT_EQ(m.roi, (Roi{10, 20, 128, 96}));
  EXPECT_EQ(m.field_w, 320);
  EXPECT_EQ(m.field_h, 240);
  EXPECT_EQ(m.dwell_ns, 250u);
  EXPECT_EQ(m.bits, 8);
  EXPECT_EQ(m.target, 1);
  EXPECT_EQ(m.seq, 0u);
  EXPECT_EQ(m.truth_count, 2);
  EXPECT_TRUE(m.truth[0].present);
  EXPECT_TRUE(m.truth[1].present);
  EXPECT_FALSE(m.truth[2].present);
  // Modelled compute time moves the next scan's start.
  src.advance_virtual_ns(1'000'000);
  ASSERT_EQ(src.start({{0, 0, 64, 64}, 500, 0}, pool[0]), StartResult::kStarted);
  EXPECT_EQ(pool[0].meta.t_scan_start_ns, t0 + expected + 1'000'000);
  EXPECT_EQ(pool[0].meta.seq, 1u);
  EXPECT_EQ(src.poll(), PollResult::kDone);
}

TEST(SimSource, RealClockPollIsBusyUntilTheScanTimeHasPassed) {
  const ScanLimits lim = small_limits();
  SimSource src(lim, moving_config("real"));
  EXPECT_FALSE(src.is_virtual_time());
  FramePool pool(1, 64);
  // 8x8 at 10 µs: 640 µs + 8 flybacks = 656 µs.
  ASSERT_EQ(src.start({{0, 0, 8, 8}, 10'000, 0}, pool[0]), StartResult::kStarted);
  const std::int64_t end = pool[0].meta.t_scan_end_ns;
  EXPECT_EQ(end - pool[0].meta.t_scan_start_ns, 656'000);
  // No assumption on how fast this thread runs (a loaded or sanitized run can first poll after
  // the 656 µs): every kBusy must come before the scan's end, kDone only after it.
  PollResult r = PollResult::kBusy;
  for (;;) {
    const std::int64_t before = rt::now_ns();
    r = src.poll();
    if (r != PollResult::kBusy) break;
    EXPECT_LT(before, end) << "busy after the scan time had passed";
  }
  EXPECT_EQ(r, PollResult::kDone);
  EXPECT_GE(rt::now_ns(), end);
}

TEST(SimSource, RequestsAreCheckedAgainstTheLimits) {
  const ScanLimits lim = small_limits();
  SimSource src(lim, moving_config("virtual"));
  FramePool pool(1, 320 * 240);
  FrameSlot& s = pool[0];
  auto start = [&](Roi r, std::uint32_t dwell) {
    const StartResult res = src.start({r, dwell, 0}, s);
    if (res == StartResult::kStarted) src.poll();
    return res;
  };
  EXPECT_EQ(start({0, 0, 320, 240}, 250), StartResult::kStarted) << "the full field is always allowed";
  EXPECT_EQ(start({0, 0, 200, 100}, 250), StartResult::kBadRequest) << "above max ROI";
  EXPECT_EQ(start({250, 0, 128, 64}, 250), StartResult::kBadRequest) << "outside the field";
  EXPECT_EQ(start({-1, 0, 64, 64}, 250), StartResult::kBadRequest);
  EXPECT_EQ(start({0, 0, 0, 64}, 250), StartResult::kBadRequest);
  EXPECT_EQ(start({0, 0, 64, 64}, 50), StartResult::kBadRequest) << "dwell below min";
  EXPECT_EQ(start({0, 0, 64, 64}, 20'000), StartResult::kBadRequest) << "dwell above max";
  EXPECT_EQ(start({192, 112, 128, 128}, 270), StartResult::kStarted);
  EXPECT_EQ(s.meta.dwell_ns, 250u) << "rounded to the 50 ns step";
  FramePool tiny(1, 100);
  EXPECT_EQ(src.start({{0, 0, 64, 64}, 250, 0}, tiny[0]), StartResult::kNoRoom);
}

TEST(SimSource, VirtualTimeIsDeterministicFromTheSeed) {
  const ScanLimits lim = small_limits();
  auto run = [&](std::uint64_t seed) {
    config::SimConfig c = moving_config("virtual");
    c.seed = seed;
    SimSource src(lim, c);
    FramePool pool(1, 128 * 128);
    std::vector<Pixel> all;
    for (int f = 0; f < 5; ++f) {
      EXPECT_EQ(src.start({{40 * f, 30, 128, 128}, 250, 0}, pool[0]), StartResult::kStarted);
      src.poll();
      all.insert(all.end(), pool[0].pixels, pool[0].pixels + 128 * 128);
      all.push_back(static_cast<Pixel>(pool[0].meta.truth[0].x_px * 100));
    }
    return all;
  };
  EXPECT_EQ(run(7), run(7));
  EXPECT_NE(run(7), run(8));
}

TEST(SimSource, MotionDuringTheScanSkewsTheTarget) {
  // A target moving fast in x is drawn further right on later lines, like a real beam scan.
  ScanLimits lim = small_limits();
  config::SimConfig c = test::clean_config();
  config::SimTargetConfig t;
  t.texture.source = "lamella";
  t.width_px = 20, t.height_px = 120;
  t.x_px = 100, t.y_px = 120;
  t.trajectory.kind = "linear";
  t.trajectory.vx_px_s = 2000;
  t.trajectory.margin_px = 0;
  c.targets = {t};
  SimSource src(lim, c);
  std::vector<Pixel> px(320 * 240);
  TargetTruth truth[kMaxTargets];
  src.render({0, 0, 320, 240}, 100, SimSource::kVirtualEpochNs, 0, px.data(), truth);
  auto left_edge = [&](int row) {
    for (int x = 0; x < 320; ++x) if (px[row * 320 + x] > 60) return x;
    return -1;
  };
  const double line_s = (320 * 100 + lim.line_flyback_ns) * 1e-9;
  const double expected_shift = 2000 * line_s * 100;  // 100 lines apart
  EXPECT_NEAR(left_edge(170) - left_edge(70), expected_shift, 1.5);
  EXPECT_NEAR(truth[0].x_px, 100 + 2000 * 0.5 * lim.scan_time_ns(320, 240, 100) * 1e-9, 1e-6);
}

TEST(SimSource, NoAllocationInStartAndPoll) {
  const ScanLimits lim = small_limits();
  SimSource src(lim, moving_config("virtual"));
  FramePool pool(2, 320 * 240);
  std::uint64_t allocs = 0;
  {
    rt::alloc::ScopedArm arm;
    for (int f = 0; f < 200; ++f) {
      const Roi roi = f % 50 == 0 ? Roi{0, 0, 320, 240} : Roi{(f * 7) % 192, (f * 3) % 112, 128, 128};
      if (src.start({roi, 250u + 50u * static_cast<std::uint32_t>(f % 4), 0}, pool[f % 2]) != StartResult::kStarted) break;
      while (src.poll() != PollResult::kDone) {
      }
      src.advance_virtual_ns(100'000);
    }
    allocs = rt::alloc::this_thread_allocations();
  }
  EXPECT_EQ(allocs, 0u);
  EXPECT_EQ(pool[1].meta.seq, 199u);
}

TEST(SourceFactory, MakesSimAndExplainsErrors) {
  rt::Status st;
  auto sim = make_scan_source("sim", small_limits(), moving_config("virtual"), {}, st);
  ASSERT_NE(sim, nullptr) << st.message;
  EXPECT_TRUE(st.ok);
  auto bad = make_scan_source("camera", small_limits(), {}, {}, st);
  EXPECT_EQ(bad, nullptr);
  EXPECT_NE(st.message.find("camera"), std::string::npos);
  auto no_dir = make_scan_source("replay", small_limits(), {}, {}, st);
  EXPECT_EQ(no_dir, nullptr);
  EXPECT_NE(st.message.find("replay.frames_dir"), std::string::npos);
  config::SimConfig missing = moving_config("virtual");
  missing.targets[0].texture.source = "image";
  missing.targets[0].texture.path = "/nonexistent/needle.pgm";
  auto m = make_scan_source("sim", small_limits(), missing, {}, st);
  EXPECT_EQ(m, nullptr);
  EXPECT_NE(st.message.find("/nonexistent/needle.pgm"), std::string::npos) << st.message;
}

TEST(SimPattern, DefaultNeedlePatternIsCentredAndAveragingReducesNoise) {
  ScanLimits lim;
  config::SimConfig c;
  c.targets[0].texture.path = std::string(SEMPOSE_TEST_DATA) + "/sem/needle_contact_eb.pgm";
  const Image p1 = render_sim_pattern(c, lim, 0, 96, 1, 250, 5);
  const Image p10 = render_sim_pattern(c, lim, 0, 96, 10, 250, 5);
  config::SimConfig clean = c;
  clean.noise = false;
  const Image ref = render_sim_pattern(clean, lim, 0, 96, 1, 250, 5);
  ASSERT_EQ(p10.width, 96);
  ASSERT_EQ(p10.height, 96);
  auto rms = [&](const Image& a) {
    double s = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) s += std::pow(a.pixels[i] - ref.pixels[i], 2);
    return std::sqrt(s / a.pixels.size());
  };
  // √10 ≈ 3.2 less noise; allow for jitter and quantisation.
  EXPECT_GT(rms(p1) / rms(p10), 2.5);
  // The needle (bright) covers the pattern centre.
  EXPECT_GT(ref.at(47, 47), 120);
}

// The recorded pattern shows the very scene the source renders: the pattern's seed selects only
// its noise, never another procedural background (a different background under the pattern's
// rim dragged tracked poses by ~0.2 px along the target's own axis).
TEST(SimPattern, RecordsTheSameSceneTheSourceRenders) {
  ScanLimits lim;
  config::SimConfig c;
  c.targets[0].texture.path = std::string(SEMPOSE_TEST_DATA) + "/sem/needle_contact_eb.pgm";
  c.seed = 3;
  c.noise = false;
  c.clock = "virtual";
  c.drift.clear();
  c.brightness_drift = 0;
  c.targets[0].x_px = 300.5;  // 300.5 − 47.5 is a whole pixel: render_sim_pattern keeps it there
  c.targets[0].y_px = 200.5;
  c.targets[0].trajectory = config::TrajectoryConfig{};
  const Image pattern = render_sim_pattern(c, lim, 0, 96, 1, 250, 12345);
  SimSource src(lim, c);
  std::vector<Pixel> roi(96 * 96);
  TargetTruth truth[kMaxTargets];
  src.render({253, 153, 96, 96}, 250, SimSource::kVirtualEpochNs, 0, roi.data(), truth);
  int differ = 0;
  for (std::size_t i = 0; i < roi.size(); ++i) differ += roi[i] != pattern.pixels[i];
  EXPECT_EQ(differ, 0) << "pixels of the recorded pattern that differ from the scene";
}

}  // namespace
}  // namespace sempose::hal
