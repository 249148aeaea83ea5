// Tracker behaviour on the simulated SEM: acquisition at several doses and angles, tracking
// accuracy, loss on blank/saturated/constant/bad frames and recovery, setup errors, and the
// zero-allocation proof over >= 1000 frames.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/angle.hpp"
#include "sempose/pose/detector_lag.hpp"
#include "sempose/pose/roi_rescaler.hpp"
#include "sim_harness.hpp"

using namespace sempose;
using namespace sempose::pose;
using namespace sempose::pose::testing;

namespace {

// Defaults but a 2° bank: half the setup time, same algorithm.
config::TrackerConfig small_config() {
  config::TrackerConfig c;
  c.angle_step_deg = 2;
  return c;
}

PatternImage flat_image(int w, int h, std::uint16_t v) {
  PatternImage im;
  im.width = w;
  im.height = h;
  im.pixels.assign(static_cast<std::size_t>(w) * h, v);
  return im;
}

double angle_error(double a, double b) { return std::fabs(std::fmod(a - b + 540.0, 360.0) - 180.0); }

}  // namespace

TEST(TrackerCreate, RejectsBadPatterns) {
  config::TrackerConfig c;
  hal::ScanLimits lim;
  rt::Status st;
  EXPECT_EQ(Tracker::create(c, {}, lim, st), nullptr);
  EXPECT_NE(st.message.find("no pattern"), std::string::npos) << st.message;

  std::vector<PatternSet> empty(1);
  EXPECT_EQ(Tracker::create(c, empty, lim, st), nullptr);
  EXPECT_NE(st.message.find("empty"), std::string::npos) << st.message;

  std::vector<PatternSet> nonsquare(1);
  nonsquare[0].image = flat_image(128, 100, 5);
  EXPECT_EQ(Tracker::create(c, nonsquare, lim, st), nullptr);
  EXPECT_NE(st.message.find("square"), std::string::npos) << st.message;

  std::vector<PatternSet> big(1);
  big[0].image = flat_image(200, 200, 5);
  EXPECT_EQ(Tracker::create(c, big, lim, st), nullptr);
  EXPECT_NE(st.message.find("larger than tracker.roi_size_px"), std::string::npos) << st.message;

  std::vector<PatternSet> flat(1);
  flat[0].image = flat_image(128, 128, 9);
  EXPECT_EQ(Tracker::create(c, flat, lim, st), nullptr);
  EXPECT_NE(st.message.find("flat"), std::string::npos) << st.message;
}

// The rotational order each pattern declares (pattern_symmetry.hpp): the procedural lamella looks
// the same turned by 180° (its angle is known modulo 180°, and its poses say so); the needle tip
// and the lamella on its post (the post breaks the lamella's symmetry) do not. Recorded at a high
// and a low dose (the pattern's own noise lowers its self-similarity and the off-pose score alike).
TEST(TrackerSymmetry, SimulatedTargetsDeclareTheirOrder) {
  for (double dose : {20.0, 2.5}) {
    for (const auto& [target, order] : {std::pair{"needle_tip", 1}, std::pair{"lamella_post", 1}, std::pair{"lamella", 2}}) {
      Scenario s;
      s.target = target;
      s.dose_e = dose;
      s.frames = 2;
      SimHarness h(s, small_config());
      ASSERT_TRUE(h.status().ok) << h.status().message;
      const PatternSymmetry sym = h.tracker()->symmetry(0);
      std::printf("%-12s dose %4.1f: order %d, turned 180/120/90/60: %.3f %.3f %.3f %.3f, same look from %.3f\n", target, dose,
                  sym.order, sym.self_score[0], sym.self_score[1], sym.self_score[2], sym.self_score[3], sym.same_look_score);
      EXPECT_EQ(sym.order, order) << target << " at " << dose << " e-/px";
      h.run();
      EXPECT_EQ(h.poses().back().angle_order, order) << "the pose declares its pattern's order";
    }
  }
}

// A drawn cross looks the same turned by 90°: order 4. Without one arm (a T) it looks like
// nothing turned: order 1 (a detail that breaks the symmetry is declared, not averaged away).
TEST(TrackerSymmetry, CrossIsFourFoldAndATeeIsNot) {
  const auto draw = [](bool left_arm) {
    const int n = 128;
    PatternImage im = flat_image(n, n, 50);
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const int u = x - n / 2, v = y - n / 2;
        const bool bar_h = std::abs(v) < 8 && std::abs(u) < 44 && (left_arm || u > -8);
        const bool bar_v = std::abs(u) < 8 && std::abs(v) < 44;
        const auto texture = static_cast<std::uint16_t>((static_cast<unsigned>(x * 7919 + y * 104729) >> 3) % 9);
        im.pixels[static_cast<std::size_t>(y) * n + x] = static_cast<std::uint16_t>((bar_h || bar_v ? 200 : 50) + texture);
      }
    return im;
  };
  hal::ScanLimits lim;
  lim.field_w = 640;
  lim.field_h = 480;
  lim.max_roi_w = lim.max_roi_h = 256;
  for (const auto& [left_arm, order] : {std::pair{true, 4}, std::pair{false, 1}}) {
    std::vector<PatternSet> sets(1);
    sets[0].image = draw(left_arm);
    rt::Status st;
    auto t = Tracker::create(small_config(), std::move(sets), lim, st);
    ASSERT_NE(t, nullptr) << st.message;
    const PatternSymmetry sym = t->symmetry(0);
    std::printf("%s: order %d, turned 180/120/90/60: %.3f %.3f %.3f %.3f, same look from %.3f\n", left_arm ? "cross" : "tee",
                sym.order, sym.self_score[0], sym.self_score[1], sym.self_score[2], sym.self_score[3], sym.same_look_score);
    EXPECT_EQ(sym.order, order) << (left_arm ? "the cross" : "the tee");
  }
}

// A fine random texture (2 px grains: a particle field, a rough surface) scores ~0 a pose 3 px
// off, so its copy turned by 90° at ~0.1 passed the "as well as a pose off the target" rule and
// order 4 (or 6) was declared: every pose's angle said known modulo 90° only (hostile round 13).
// A same look must score at least PatternSymmetry::kMinSameLookScore too.
TEST(TrackerSymmetry, AFineRandomTextureIsNotSymmetric) {
  const int n = 128;
  PatternImage im = flat_image(n, n, 0);
  std::uint32_t state = 2;
  std::vector<std::uint16_t> grains(static_cast<std::size_t>(n / 2) * (n / 2));
  for (auto& g : grains) {
    state = state * 1664525u + 1013904223u;
    g = static_cast<std::uint16_t>(state >> 24);
  }
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      im.pixels[static_cast<std::size_t>(y) * n + x] = grains[static_cast<std::size_t>(y / 2) * (n / 2) + x / 2];
  hal::ScanLimits lim;
  lim.field_w = 640;
  lim.field_h = 480;
  lim.max_roi_w = lim.max_roi_h = 256;
  std::vector<PatternSet> sets(1);
  sets[0].image = im;
  rt::Status st;
  auto t = Tracker::create(small_config(), std::move(sets), lim, st);
  ASSERT_NE(t, nullptr) << st.message;
  const PatternSymmetry sym = t->symmetry(0);
  std::printf("random grains: order %d, turned 180/120/90/60: %.3f %.3f %.3f %.3f, same look from %.3f\n", sym.order,
              sym.self_score[0], sym.self_score[1], sym.self_score[2], sym.self_score[3], sym.same_look_score);
  EXPECT_EQ(sym.order, 1) << "a turned copy scoring " << sym.self_score[2] << " was declared the same look";
}

// Start search finds the target at paper-like noise, several doses and angles.
class Acquire : public ::testing::TestWithParam<std::tuple<double, double>> {};
TEST_P(Acquire, FindsTargetOnFullField) {
  Scenario s;
  s.motion = "static";
  s.dose_e = std::get<0>(GetParam());
  s.start_phi_deg = std::get<1>(GetParam());
  s.start_x_px = 250;
  s.start_y_px = 300;
  s.frames = 10;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const PoseEstimate& e = h.poses()[0];
  EXPECT_TRUE(e.searched);
  // Found, and reported UNCERTAIN: a first start's search frame is one field scan nothing has
  // confirmed yet (README: States); the ROI frames after it confirm it.
  EXPECT_EQ(e.state, TrackState::kUncertain) << "score " << e.score << " state " << to_string(e.state);
  const auto& tr = h.truth()[0];
  EXPECT_LT(std::hypot(e.x_px - tr.x_px, e.y_px - tr.y_px), 1.0);
  EXPECT_LT(angle_error(e.phi_deg, tr.phi_deg), 2.0);
  // The following ROI frames keep it (and settle the flip check within 10 frames).
  const PoseEstimate& last = h.poses().back();
  EXPECT_EQ(last.state, TrackState::kTracking) << to_string(last.state);
  EXPECT_LT(std::hypot(last.x_px - h.truth().back().x_px, last.y_px - h.truth().back().y_px), 1.5);
  EXPECT_FALSE(last.searched);
}
INSTANTIATE_TEST_SUITE_P(DosesAngles, Acquire,
                         ::testing::Combine(::testing::Values(20.0, 6.0, 2.5),
                                            ::testing::Values(0.0, 37.0, -120.0, 179.0)));

TEST(Tracker, FollowsSmoothMotionAccurately) {
  Scenario s;
  s.motion = "smooth";
  s.dose_e = 6;
  s.frames = 120;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const RunStats r = h.stats();
  EXPECT_EQ(r.tracked, r.frames - 1) << "every frame but the start search's, which waits for the next to confirm it";
  EXPECT_LT(r.rms_px(), 0.6);
  EXPECT_LT(r.rms_deg(), 1.0);
  EXPECT_LT(r.max_px, 2.0);
  EXPECT_EQ(r.searches, 1);
}

TEST(Tracker, RecoversFromJumps) {
  Scenario s;
  s.motion = "jump";
  s.dose_e = 6;
  s.frames = 150;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const RunStats r = h.stats();
  EXPECT_GE(r.jumps, 2);
  EXPECT_LE(r.recovery_max, 3);
  EXPECT_GT(r.tracked_share(), 0.8);
  // Right after a jump the old ROI holds look-alike texture: it must not be reported as
  // TRACKING (every TRACKING pose within 3 px of the truth).
  EXPECT_EQ(r.false_tracking, 0) << "worst TRACKING pose " << r.false_max_px << " px off";
}

TEST(Tracker, FlatBadAndOffFieldFramesAreLostNeverNan) {
  Scenario s;
  s.motion = "static";
  s.frames = 3;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok);
  h.run();
  Tracker& t = *h.tracker();
  ASSERT_EQ(h.poses().back().state, TrackState::kTracking);
  std::vector<hal::Pixel> px(640 * 480);
  for (hal::Pixel level : {hal::Pixel{0}, hal::Pixel{255}, hal::Pixel{128}}) {
    std::fill(px.begin(), px.end(), level);
    hal::FrameMeta m;
    m.roi = t.next_roi();
    m.field_w = 640;
    m.field_h = 480;
    const PoseEstimate e = t.update(pipeline::to_pose_frame(m, px.data()));
    EXPECT_NE(e.state, TrackState::kTracking);
    EXPECT_EQ(e.score, 0.0f);
    EXPECT_TRUE(std::isfinite(e.x_px) && std::isfinite(e.y_px) && std::isfinite(e.phi_deg));
  }
  // Now acquiring: next ROI is the full field; a blank full field stays ACQUIRING.
  const hal::Roi full = t.next_roi();
  EXPECT_EQ(full.w, 640);
  EXPECT_EQ(full.h, 480);
  hal::FrameMeta m;
  m.roi = full;
  m.field_w = 640;
  m.field_h = 480;
  EXPECT_EQ(t.update(pipeline::to_pose_frame(m, px.data())).state, TrackState::kAcquiring);
  m.status = hal::FrameStatus::kBad;
  const PoseEstimate bad = t.update(pipeline::to_pose_frame(m, px.data()));
  EXPECT_EQ(bad.reason_bits & kReasonBadFrame, kReasonBadFrame);
  EXPECT_NE(bad.state, TrackState::kTracking);
  EXPECT_NE(t.update(pipeline::to_pose_frame(m, nullptr)).state, TrackState::kTracking);
  // A frame smaller than the pattern (e.g. clamped at the field edge).
  m.status = hal::FrameStatus::kOk;
  m.roi = {600, 450, 40, 30};
  EXPECT_NE(t.update(pipeline::to_pose_frame(m, px.data())).state, TrackState::kTracking);
}

TEST(Tracker, TargetLeavingTheFieldIsLost) {
  Scenario s;
  s.motion = "fast";
  s.dose_e = 6;
  s.frames = 150;
  SimHarness h(s, small_config());
  h.run();
  for (const auto& e : h.poses()) {
    EXPECT_TRUE(std::isfinite(e.x_px) && std::isfinite(e.score));
    EXPECT_GE(e.score, -1.0f);
    EXPECT_LE(e.score, 1.0f);
  }
}

TEST(Tracker, ReacquireAndPatternSetSelection) {
  Scenario s;
  s.motion = "static";
  s.frames = 2;
  SimHarness h(s, small_config());
  h.run();
  Tracker& t = *h.tracker();
  EXPECT_FALSE(t.select_pattern_set(3));
  EXPECT_TRUE(t.select_pattern_set(0));
  EXPECT_EQ(t.pattern_set(), 0);
  t.request_reacquire();
  EXPECT_EQ(t.next_roi().w, 640);
  EXPECT_GT(t.memory_bytes(), 0u);
}

TEST(Tracker, SelectsExpectedScaleFromMicroscopeNmPerPx) {
  // The target is 1.2× its pattern's size from the first frame (the microscope zoomed in from
  // the pattern's 40 nm/px to 33.3 nm/px). Told so by SELECT's nm/px, the start search looks
  // near 1.2 only (one level, ±15 %) and the first tracked poses are at 1.2; untold, it
  // searches 0.8 / 1 / 1.25 around 1 and finds 1.2 too (the evidence is clear: a rigid
  // target); told a wrong nm/px (44.4: scale 0.9), it searches only near 0.9 and starts below 1.1.
  auto first_tracked = [](double told_nm_per_px) {
    Scenario s;
    s.target = "needle_tip";
    s.motion = "static";
    s.scale_from = s.scale_to = 1.2;
    s.dose_e = 20;
    s.frames = 6;
    SimHarness h(s, small_config());
    EXPECT_TRUE(h.status().ok) << h.status().message;
    if (told_nm_per_px > 0) {
      EXPECT_TRUE(h.tracker()->select_pattern_set(0, told_nm_per_px));
    }
    h.run();
    for (const auto& e : h.poses()) {
      if (e.state == TrackState::kTracking && !e.searched) return e;
    }
    return PoseEstimate{};
  };
  const PoseEstimate told = first_tracked(40.0 / 1.2), untold = first_tracked(0), told_wrong = first_tracked(40.0 / 0.9);
  EXPECT_EQ(told.state, TrackState::kTracking);
  EXPECT_NEAR(told.scale, 1.2, 0.04) << "SELECT's nm/px sets the scale tracking starts at";
  EXPECT_NEAR(untold.scale, 1.2, 0.04) << "without it the start search covers scale";
  EXPECT_LT(told_wrong.scale, 1.1) << "told scale 0.9, the search stays near it (the test would not tell them apart)";
  // The same set at the same scale again is not a new look: no new search.
  Scenario s;
  s.motion = "static";
  s.frames = 2;
  SimHarness h(s, small_config());
  h.run();
  Tracker& t = *h.tracker();
  EXPECT_TRUE(t.select_pattern_set(0, 40.0));
  EXPECT_NE(t.next_roi().w, 640) << "same set, same scale: keeps tracking";
  // Told a size the tracker cannot follow (2x, 1000x, 1/1000x the pattern's): refused, nothing
  // searched (the 2x one used to be clamped to 1.45 and taken).
  for (const double nm : {20.0, 0.04, 40000.0}) EXPECT_FALSE(t.select_pattern_set(0, nm)) << nm << " nm/px";
  EXPECT_NE(t.next_roi().w, 640) << "a refused SELECT changes nothing";
  EXPECT_TRUE(t.select_pattern_set(0, 30.0));
  EXPECT_EQ(t.next_roi().w, 640) << "same set at 1.33 times the magnification: searched again";
}

// No SELECT, the target at 0.8 or 1.25 of its pattern's size from the first frame: the start
// search covers scale, so the first pose is already at the target's scale and the tracked
// ones keep it (at scale 1 only, a 1.25 target was found off by its size and tracked from 1).
class AcquireScaled : public ::testing::TestWithParam<std::tuple<const char*, double>> {};
TEST_P(AcquireScaled, FirstPoseHasTheTargetsScale) {
  Scenario s;
  s.target = std::get<0>(GetParam());
  s.scale_from = s.scale_to = std::get<1>(GetParam());
  s.motion = "static";
  s.dose_e = 6;
  s.start_phi_deg = 37;
  s.start_x_px = 300;
  s.start_y_px = 230;
  s.frames = 10;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const PoseEstimate& e = h.poses()[f];
    const auto& tr = h.truth()[f];
    EXPECT_EQ(e.searched, f == 0) << "frame " << f;
    // The procedural lamella is nearly 180°-symmetric: UNCERTAIN until the flip check settles
    // (README: States), the pose right all the same; TRACKING by the last frame.
    // The search frame itself waits for the next frame to confirm it: UNCERTAIN.
    const bool flip_check = std::string(s.target) == "lamella" && f + 1 < h.poses().size();
    if (f == 0) {
      EXPECT_EQ(e.state, TrackState::kUncertain) << "the start search's frame, score " << e.score;
    } else {
      ASSERT_TRUE(e.state == TrackState::kTracking || (flip_check && e.state == TrackState::kUncertain))
          << "frame " << f << " score " << e.score << " " << to_string(e.state);
    }
    EXPECT_NEAR(e.scale, tr.scale, 0.04) << "frame " << f;
    EXPECT_LT(std::hypot(e.x_px - tr.x_px, e.y_px - tr.y_px), 1.5) << "frame " << f;
    EXPECT_LT(angle_error(e.phi_deg, tr.phi_deg), 2.0) << "frame " << f;
  }
}
INSTANTIATE_TEST_SUITE_P(TargetsScales, AcquireScaled,
                         ::testing::Combine(::testing::Values("needle_tip", "lamella_post", "lamella"),
                                            ::testing::Values(0.8, 1.25)));

// After a loss the search covers scale too: a 1.25 target that jumps is re-found at 1.25.
TEST(Tracker, ReSearchAfterJumpFindsScale) {
  Scenario s;
  s.target = "needle_tip";
  s.scale_from = s.scale_to = 1.25;
  s.motion = "jump";
  s.dose_e = 6;
  s.frames = 120;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  int found = 0;
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const PoseEstimate& e = h.poses()[f];
    if (!e.searched || e.state != TrackState::kTracking) continue;
    ++found;
    EXPECT_NEAR(e.scale, 1.25, 0.04) << "frame " << f;
    EXPECT_LT(std::hypot(e.x_px - h.truth()[f].x_px, e.y_px - h.truth()[f].y_px), 2.0) << "frame " << f;
  }
  EXPECT_GE(found, 2) << "at least two re-searches after a jump (the start search waits for the next frame)";
}

// The expected scale is a prior, not a free parameter: the start search moves off it only on
// clear evidence (StartSearch, ScaleEvidenceCheck). A rigid needle at 1.25 of its pattern's
// size is found at 1.25 even at 2.5 e⁻/px. A gripper whose jaws are held open 4 or 8 px each (its
// pattern recorded closed) matches a rigid pattern stretched by 1.1–1.27 a little better — but
// far less than a rigid larger target would — so it stays at the expected scale 1 (tracking
// started at 1.10–1.17 dragged the body 3–4 px in the benchmark's jaws rows).
TEST(ScalePrior, ClearScaleIsTakenDeformedTargetStaysAtTheExpectedOne) {
  auto first_pose = [](const char* target, double scale, double jaws_open_px, double dose) {
    Scenario s;
    s.target = target;
    s.scale_from = s.scale_to = scale;
    s.jaws_open_px = jaws_open_px;
    s.motion = "static";
    s.dose_e = dose;
    s.start_phi_deg = 30;
    s.frames = 2;  // the search frame and the ROI frame that confirms it (or not)
    SimHarness h(s, small_config());
    EXPECT_TRUE(h.status().ok) << h.status().message;
    h.run();
    EXPECT_EQ(h.poses().size(), 2u);
    EXPECT_TRUE(h.poses()[0].searched);
    PoseEstimate e = h.poses()[0];
    e.state = h.poses()[1].state;  // the target stands still: the next frame confirms this pose or not
    return std::pair{e, h.truth()[0]};
  };
  for (double dose : {6.0, 2.5}) {
    const auto [e, tr] = first_pose("needle_tip", 1.25, 0, dose);
    EXPECT_EQ(e.state, TrackState::kTracking) << "dose " << dose;
    EXPECT_NEAR(e.scale, 1.25, 0.04) << "a rigid target's other scale is clear, dose " << dose;
    EXPECT_LT(std::hypot(e.x_px - tr.x_px, e.y_px - tr.y_px), 1.5) << "dose " << dose;
  }
  // Without the rule (every away scale taken) these found 1.10 / 1.11 at 4 px and 1.25 / 1.27
  // at 8 px (dose 20 / 6).
  for (double jaws_px : {4.0, 8.0}) {
    for (double dose : {20.0, 6.0}) {
      const auto [e, tr] = first_pose("gripper", 1.0, jaws_px, dose);
      EXPECT_NEAR(e.scale, 1.0, RoiRescaler::kMinChange)
          << "open jaws are no evidence of a larger gripper: jaws " << jaws_px << " px, dose " << dose;
      if (e.state == TrackState::kTracking) {
        EXPECT_LT(std::hypot(e.x_px - tr.x_px, e.y_px - tr.y_px), 3.0) << "jaws " << jaws_px << " px, dose " << dose;
      }
    }
  }
}

TEST(Tracker, NoHeapAllocationOverThousandFrames) {
  Scenario s;
  s.motion = "jump";  // searches, losses and tracking all happen
  s.dose_e = 2.5;
  s.frames = 1000;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok);
  h.run();  // arms the counter around every update() and next_roi()
  EXPECT_EQ(h.tracker_allocations(), 0u);
  // The counter itself works here (the test could fail):
  {
    rt::alloc::ScopedArm arm;
    const auto before = rt::alloc::this_thread_allocations();
    std::vector<int> v(100);  // a real heap call (not elided like new/delete pairs)
    v[3] = 1;
    EXPECT_GT(rt::alloc::this_thread_allocations(), before);
  }
  const RunStats r = h.stats();
  EXPECT_GT(r.searches, 1);
  EXPECT_GT(r.tracked, 500);
}

// tracker.correct_scan_motion takes the scan's motion bias out of the reported pose only: every
// rule judges the pose as measured (they were measured on such poses; with the correction inside
// them pose_envelope_probe had 69 -> 96 false TRACKING poses), the next ROI is placed from it, so
// the stream's states and ROIs are the same either way, and on a fast target the reported angle
// moves by the bias (the scan's shear read as a turn).
TEST(Tracker, ScanMotionCorrectionMovesTheReportedPoseOnly) {
  Scenario s;
  s.target = "needle_tip";
  s.motion = "fast";
  s.dose_e = 6.0;
  s.frames = 60;
  std::vector<PoseEstimate> poses[2];
  std::vector<Roi> rois[2];
  for (int on = 0; on < 2; ++on) {
    config::TrackerConfig tc = small_config();
    tc.correct_scan_motion = on == 1;
    SimHarness h(s, tc);
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    poses[on] = h.poses();
    rois[on] = h.next_rois();
  }
  ASSERT_EQ(poses[0].size(), poses[1].size());
  int moved = 0;
  for (std::size_t f = 0; f < poses[0].size(); ++f) {
    const PoseEstimate &off = poses[0][f], &on = poses[1][f];
    ASSERT_EQ(off.state, on.state) << "frame " << f;
    ASSERT_EQ(off.reason_bits, on.reason_bits) << "frame " << f;
    ASSERT_EQ(rois[0][f].x, rois[1][f].x) << "frame " << f;
    ASSERT_EQ(rois[0][f].y, rois[1][f].y) << "frame " << f;
    EXPECT_EQ(off.score, on.score) << "frame " << f;
    if (std::fabs(rt::wrap_deg(on.phi_deg - off.phi_deg)) > 0.05) ++moved;
  }
  std::printf("scan-motion correction: %d of %zu poses turned by more than 0.05 deg, every state and ROI the same\n", moved,
              poses[0].size());
  EXPECT_GE(moved, 20) << "the correction should reach the reported pose on a fast target";
}

// tracker.filter: off, the reported pose is the frame's measurement; on, it is filtered (less
// noise on a still target) while meas_* keep the raw measurement.
TEST(Tracker, PoseFilterSmoothsTheReportedPoseOnly) {
  Scenario s;
  s.motion = "static";
  s.dose_e = 2.5;
  s.frames = 60;
  auto run = [&](bool enabled, double& rms_out, double& rms_meas) {
    config::TrackerConfig tc;
    tc.filter.enabled = enabled;
    tc.filter.meas_sigma_px = 0.4;
    tc.filter.meas_sigma_deg = 0.8;
    SimHarness h(s, tc);
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    double sum = 0, sum_meas = 0;
    int n = 0;
    for (int f = 10; f < s.frames; ++f) {
      const PoseEstimate& e = h.poses()[static_cast<std::size_t>(f)];
      const hal::TargetTruth& t = h.truth()[static_cast<std::size_t>(f)];
      ASSERT_EQ(e.state, TrackState::kTracking);
      if (!enabled) {
        ASSERT_EQ(e.x_px, e.meas_x_px);
      }
      sum += std::pow(e.x_px - t.x_px, 2) + std::pow(e.y_px - t.y_px, 2);
      sum_meas += std::pow(e.meas_x_px - t.x_px, 2) + std::pow(e.meas_y_px - t.y_px, 2);
      ++n;
    }
    rms_out = std::sqrt(sum / n);
    rms_meas = std::sqrt(sum_meas / n);
  };
  double off = 0, off_meas = 0, on = 0, on_meas = 0;
  run(false, off, off_meas);
  run(true, on, on_meas);
  EXPECT_DOUBLE_EQ(off, off_meas);
  // The measurements themselves do not change, but for the scan's motion bias taken out of them
  // (tracker.correct_scan_motion): its rates come from the reported poses' trail, filtered when
  // the filter is on (a still target: ~1e-4 px).
  EXPECT_NEAR(on_meas, off_meas, 0.01);
  EXPECT_LT(on, 0.8 * on_meas) << "filtered " << on << " px vs raw " << on_meas << " px";
}

// Issue 13: recovery after a jump at least as before the dose-1 rule. The procedural lamella at
// 6 e-/px scores ~0.70 before its jumps and 0.57-0.61 after (other background): below the
// explained bound, where the stream's pose noise is required. With the noise known from before
// the loss (same target, same dwell) the re-acquired pose is TRACKING on the search frame or the
// one after it; before, it waited for three ROI frames of the new stream (recovery 5-6 frames).
// No pose is TRACKING while > 3 px or > 10° off.
TEST(Tracker, TrackingAgainWithinTwoFramesOfAJump) {
  for (const auto& [target, dose] : {std::pair<const char*, double>{"lamella", 6.0}, {"needle_tip", 2.5}}) {
    Scenario s;
    s.target = target;
    s.motion = "jump";
    s.dose_e = dose;
    s.frames = 60;
    s.start_phi_deg = 30;
    SimHarness h(s, config::TrackerConfig{});
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const RunStats r = h.stats();
    EXPECT_GE(r.jumps, 1) << target;
    EXPECT_GE(r.recovery_max, 1) << target;
    EXPECT_LE(r.recovery_max, 2) << target << " at " << dose << " e-/px: frames from the jump to TRACKING < 1 px off";
    EXPECT_EQ(r.false_tracking, 0) << target << ": worst TRACKING pose " << r.false_max_px << " px off";
  }
}

// Issue 13 item 6: one pose off the target's line must not be doubled into the next prediction.
// The warped crop moving at constant velocity (fast, ~4 px a frame) is moved 2.5 px and 3° off
// its line on one frame only (a pose as a noisy frame's would be). The constant-velocity
// prediction from the last two poses put the next ROI 4.5 px off the line (~2 × 2.5: the lamella
// under charging + defocus at 2.5 e-/px, --full frame 104, then walked to a neighbouring
// maximum from a prediction 6° short); the rate fitted over the last three poses passes 4/3 of
// that pose's offset (measured 3.5 px). The ROI's centre is the prediction rounded to a pixel.
TEST(Tracker, OnePoseOffTheLineIsNotDoubledIntoThePrediction) {
  // The rate over three poses and, to show the case is one, the two-pose rate (the default).
  for (const int rate : {3, 2}) {
    Scenario s;
    s.target = "warped";
    s.motion = "fast";
    s.dose_e = 20;
    s.frames = 30;
    s.kick_frame = 20;
    s.kick_x_px = 2.5;
    s.kick_phi_deg = 3;
    config::TrackerConfig tc;
    tc.predict_rate_poses = rate;
    SimHarness h(s, tc);
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    for (int f = 12; f < s.frames; ++f) {
      const PoseEstimate& e = h.poses()[static_cast<std::size_t>(f)];
      const hal::TargetTruth& t = h.truth()[static_cast<std::size_t>(f)];
      ASSERT_EQ(e.state, TrackState::kTracking) << "frame " << f << ", rate over " << rate << " poses";
      // Never false (the frame after the pose off the line measured 1.1 px off with three poses).
      EXPECT_LT(std::hypot(e.x_px - t.x_px, e.y_px - t.y_px), 3.0) << "frame " << f << ", rate over " << rate << " poses";
    }
    auto centre_off = [&](int f) {  // the ROI asked for after frame f against frame f + 1's truth
      const pose::Roi r = h.next_rois()[static_cast<std::size_t>(f)];
      const hal::TargetTruth& t = h.truth()[static_cast<std::size_t>(f + 1)];
      return std::hypot(r.x + (r.w - 1) / 2.0 - t.x_px, r.y + (r.h - 1) / 2.0 - t.y_px);
    };
    std::printf("rate over %d poses: next ROI's centre off the truth by %.2f px on the line, %.2f px after the pose off it\n",
                rate, centre_off(18), centre_off(20));
    EXPECT_LT(centre_off(18), 1.0) << "on the line: the prediction is exact up to rounding";
    if (rate == 2) {
      EXPECT_GT(centre_off(20), 1.5 * s.kick_x_px) << "the two-pose rate doubles it (the case this test is about)";
    } else {
      EXPECT_LT(centre_off(20), 1.5 * s.kick_x_px) << "the pose off the line by " << s.kick_x_px << " px was doubled";
      EXPECT_LT(centre_off(21), 1.5 * s.kick_x_px);
    }
  }
}

// Issue 13 item 5, σ with every pose: a start search's pose carries σ as an ROI frame's does
// (it was 0, "not measured", on every search frame — a pose re-acquired after a jump TRACKING on
// its search frame came with no uncertainty). A found search frame's σx, σy, σφ, σscale are > 0
// and of the size the ROI frames right after it show (the same fit on the same target, one
// frame apart); at a scale the search found (1.25: the ROI loaded resampled) too.
TEST(Tracker, SearchFramePoseCarriesItsSigma) {
  struct Case {
    const char* target;
    double scale, dose;
  };
  for (const Case& c : {Case{"needle_tip", 1.0, 6.0}, Case{"needle_tip", 1.25, 6.0}, Case{"lamella_post", 1.0, 2.5}}) {
    Scenario s;
    s.target = c.target;
    s.scale_from = s.scale_to = c.scale;
    s.motion = "jump";
    s.dose_e = c.dose;
    s.frames = 90;
    SimHarness h(s, small_config());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const auto& poses = h.poses();
    int checked = 0;
    for (std::size_t f = 0; f + 3 < poses.size(); ++f) {
      const PoseEstimate& e = poses[f];
      if (!e.searched || (e.state != TrackState::kTracking && e.state != TrackState::kUncertain)) continue;
      const std::string at = std::string(c.target) + " scale " + std::to_string(c.scale) + " frame " + std::to_string(f);
      EXPECT_GT(e.sigma_x_px, 0.0) << at;
      EXPECT_GT(e.sigma_y_px, 0.0) << at;
      EXPECT_GT(e.sigma_phi_deg, 0.0) << at;
      EXPECT_GT(e.sigma_scale, 0.0) << at;
      // The next ROI frames' σ (those measured): the search frame's within a factor of 2.5.
      for (std::size_t g = f + 1; g <= f + 3; ++g) {
        const PoseEstimate& n = poses[g];
        if (n.searched || n.sigma_x_px <= 0) continue;
        const double sp = std::hypot(e.sigma_x_px, e.sigma_y_px), np = std::hypot(n.sigma_x_px, n.sigma_y_px);
        EXPECT_LT(sp, 2.5 * np) << at << " σ " << sp << " px, frame " << g << " " << np << " px";
        EXPECT_GT(sp, np / 2.5) << at << " σ " << sp << " px, frame " << g << " " << np << " px";
        EXPECT_LT(e.sigma_phi_deg, 2.5 * n.sigma_phi_deg) << at;
        EXPECT_GT(e.sigma_phi_deg, n.sigma_phi_deg / 2.5) << at;
        break;
      }
      ++checked;
    }
    EXPECT_GE(checked, 2) << c.target << ": the first start and at least one re-search after a jump";
  }
}

// A still target at 6 e-/px over 40 frames: its TRACKING poses' mean x and y error, and τ as
// the tracker measured it (0 when it did not).
struct StillMeanError {
  double dx = 0, dy = 0, tau_px = 0;
};
StillMeanError still_mean_error(Scenario s, const config::TrackerConfig& tc) {
  s.motion = "static";
  s.dose_e = 6;
  s.frames = 40;
  SimHarness h(s, tc);
  EXPECT_TRUE(h.status().ok) << h.status().message;
  if (!h.status().ok) return {};
  h.run();
  const RunStats r = h.stats();
  EXPECT_GT(r.err_n, 30) << s.target;
  if (r.err_n == 0) return {};
  return {r.sum_dx / r.err_n, r.sum_dy / r.err_n, h.tracker()->detector_tau_status().tau_px};
}

// The detector's bandwidth (tracker.detector_tau_ns): a first-order low-pass along each line
// delays the image by exp(-d/τ)/(1 - exp(-d/τ)) px at pixel dwell d — 0.77 px at 100 ns for
// τ = 120 ns, ~0 at the 2 µs a pattern is recorded at. The governor scans at short dwells, so a
// pose matched against that pattern sat 0.77 px along the line from the target, and moved
// whenever the dwell changed. Told τ, the tracker takes the difference out of x.
TEST(Tracker, DetectorLagAtAnotherDwellIsTakenOutOfX) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    StillMeanError err[2];
    for (int told = 0; told < 2; ++told) {
      Scenario s;
      s.target = target;
      s.dwell_ns = 100;
      s.pattern_dwell_ns = 2000;
      s.detector_tau_ns = 120;
      s.tell_detector_tau = told == 1;
      config::TrackerConfig tc = small_config();
      tc.measure_detector_tau = false;  // untold means uncorrected here (measured: the next test)
      err[told] = still_mean_error(s, tc);
    }
    const double lag = DetectorLag::px(120, 100) - DetectorLag::px(120, 2000);
    std::printf("%s: mean x error %+.3f px untold, %+.3f px told (lag %.3f px); y %+.3f / %+.3f px\n", target, err[0].dx,
                err[1].dx, lag, err[0].dy, err[1].dy);
    EXPECT_NEAR(lag, 0.769, 0.001);
    EXPECT_GT(err[0].dx, 0.5 * lag) << target << ": not told τ, x lags along the line";
    EXPECT_LT(std::fabs(err[1].dx), 0.25 * lag) << target << ": told τ, mean x error " << err[1].dx << " px (untold "
                                                << err[0].dx << ")";
    EXPECT_NEAR(err[1].dy, err[0].dy, 0.05) << target << ": y is not along the line";
  }
}

// Frames at 250 ns through a detector low-pass of τ nobody tells the tracker; the pattern
// recorded lag-free (a clean crop, its set's dwell_ns 0) or through the same detector.
Scenario untold_detector(const char* target, double tau_ns, bool pattern_lag_free) {
  Scenario s;
  s.target = target;
  s.dwell_ns = 250;
  s.detector_tau_ns = tau_ns;
  s.pattern_lag_free = pattern_lag_free;
  s.tell_detector_tau = false;
  return s;
}

// The default configuration, nobody telling τ, a clean (lag-free) pattern, frames through a
// low-pass of τ 2 px (lag 1.54 px): the lag is measured and taken out. Main had it opt-in, and
// the poses sat +1.2…+1.5 px along the line. The same frames without noise (a synthetic
// sequence): the lag cannot be told from the scene's own edges, so nothing is measured and
// nothing taken out — reading those edges put a noise-free needle 1.31 px off.
TEST(Tracker, DetectorLagOfAnUntoldDetectorIsTakenOutByDefault) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    StillMeanError err[2];
    for (int noisy = 0; noisy < 2; ++noisy) {
      Scenario s = untold_detector(target, 500, true);
      s.noise = noisy == 1;
      err[noisy] = still_mean_error(s, config::TrackerConfig{});
    }
    std::printf("%s, τ 2 px untold, default config: mean x error %+.3f px (τ read %.2f px), noise-free %+.3f px (τ read %.2f)\n",
                target, err[1].dx, err[1].tau_px, err[0].dx, err[0].tau_px);
    EXPECT_NEAR(err[1].tau_px, 2.0, 0.2) << target;
    EXPECT_LT(std::fabs(err[1].dx), 0.35) << target << ": mean x error " << err[1].dx << " px (the lag is 1.54 px)";
    EXPECT_EQ(err[0].tau_px, 0.0) << target << ": noise-free frames read no lag";
    EXPECT_GT(err[0].dx, 0.8) << target << ": noise-free, nothing is taken out";
  }
}

// Every 4th line dropped to the black level (a scan fault), nothing told (no τ, the pattern's
// set without its dwell_ns, its own noise lag-free): the dropped lines correlate the line
// differences along the lines (ρ 0.44–0.49 at 6 e⁻/px, 0.67–0.70 at 20), which the τ estimate
// took for a slow detector's and took its lag out of every pose: on 0f5fdd5 x sat −0.77/−0.92 px
// (6 e⁻/px) and −1.82/−2.28 px (20) along the line. Their ρ2 ≈ ρ1, not a low-pass's ρ1² (the
// lag-2 check): no lag is taken out (+0.03…+0.18 px), no τ reported. The same path with a real
// low-pass of τ 2 px still measures it.
TEST(Tracker, DroppedLinesAreNotTakenForASlowDetector) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    for (double dose : {20.0, 6.0}) {
      Scenario s;
      s.target = target;
      s.motion = "static";
      s.dose_e = dose;
      s.frames = 40;
      s.pattern_dwell_told = false;
      s.frame_fault = [](std::uint64_t, const hal::Roi& r, hal::Pixel* p, hal::Pixel m) {
        for (int y = 0; y < r.h; ++y)
          if ((r.y + y) % 4 == 0)
            std::fill(p + static_cast<std::ptrdiff_t>(y) * r.w, p + static_cast<std::ptrdiff_t>(y + 1) * r.w, static_cast<hal::Pixel>(0.04 * m));
      };
      SimHarness h(s, config::TrackerConfig{});
      ASSERT_TRUE(h.status().ok) << h.status().message;
      h.run();
      const RunStats r = h.stats();
      ASSERT_GT(r.err_n, 30) << target;
      const auto tau = h.tracker()->detector_tau_status();
      const double dx = r.sum_dx / r.err_n;
      std::printf("%s, every 4th line dropped, %.0f e-/px, nothing told: mean x error %+.3f px, line rho %.3f, tau %.2f px\n",
                  target, dose, dx, tau.rho, tau.tau_px);
      EXPECT_LT(std::fabs(dx), 0.3) << target << " " << dose << " e-/px: a dropped-line lag taken out";
      EXPECT_EQ(tau.tau_px, 0.0) << target << " " << dose << " e-/px";
    }
    const StillMeanError real = still_mean_error(untold_detector(target, 500, true), config::TrackerConfig{});
    EXPECT_NEAR(real.tau_px, 2.0, 0.2) << target << ": a real low-pass is still measured";
    EXPECT_LT(std::fabs(real.dx), 0.35) << target;
  }
}

// A pattern recorded through the same detector at the tracking dwell (10 still frames, the
// simulator's low-pass of τ 2 px) and given without its dwell_ns: its own noise shows the
// frames' lag, so the lags cancel and nothing is taken out. Counted lag-free (main with the
// measurement on), the frames' whole lag was taken out of poses whose pattern carries it too:
// −1.44 px on the held-out needle.
TEST(Tracker, PatternRecordedThroughTheDetectorIsNotCorrectedTwice) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    StillMeanError err[2];
    for (int dwell_told = 0; dwell_told < 2; ++dwell_told) {
      Scenario s = untold_detector(target, 500, false);
      s.pattern_dwell_told = dwell_told == 1;
      config::TrackerConfig tc;
      tc.measure_detector_tau = true;  // the default here; main had it opt-in
      err[dwell_told] = still_mean_error(s, tc);
    }
    std::printf("%s, pattern at the tracking dwell, τ 2 px untold: mean x error %+.3f px without its dwell_ns, %+.3f px with it\n",
                target, err[0].dx, err[1].dx);
    EXPECT_LT(std::fabs(err[0].dx), 0.3) << target << ": the lag taken out twice";
    EXPECT_NEAR(err[0].dx, err[1].dx, 0.25) << target;
  }
}

// Nobody tells τ (a replay, real hardware) and the pattern is a clean crop (lag-free, its set's
// dwell_ns 0) while the frames go through a detector low-pass of τ = 1 px: every pose sat the
// lag (~0.5-0.7 px) along the line, 3-6x the single-frame bound. tracker.measure_detector_tau
// reads τ from the frames' noise (line_correlation.hpp) and takes the lag out.
TEST(Tracker, DetectorLagOfAnUntoldDetectorIsMeasuredFromTheFrames) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    StillMeanError err[2];
    for (int measure = 0; measure < 2; ++measure) {
      const Scenario s = untold_detector(target, 250, true);
      config::TrackerConfig tc = small_config();
      tc.measure_detector_tau = measure == 1;
      err[measure] = still_mean_error(s, tc);
    }
    std::printf("%s: mean x error %+.3f px not measured, %+.3f px measured (τ %.3f px); y %+.3f / %+.3f px\n", target,
                err[0].dx, err[1].dx, err[1].tau_px, err[0].dy, err[1].dy);
    EXPECT_GT(err[0].dx, 0.4) << target << ": not measured, x lags along the line";
    EXPECT_NEAR(err[1].tau_px, 1.0, 0.1) << target;
    EXPECT_LT(std::fabs(err[1].dx), 0.15) << target << ": measured τ, mean x error " << err[1].dx << " px (not measured "
                                          << err[0].dx << ")";
    EXPECT_NEAR(err[1].dy, err[0].dy, 0.05) << target << ": y is not along the line";
  }
}

// A pose is valid for the time the beam passed the target, not the scan's end: a full-field
// search frame of a moving target shows it where its rows were scanned, tens of ms from mid-scan
// and up to the field's whole scan time before its end. PoseEstimate::t_beam_ns is that time (the
// CSV's t_ns, the origin of CAN's age); on the base every pose was stamped at the scan's end.
TEST(Tracker, APoseIsTimedWhenTheBeamPassedTheTarget) {
  Scenario s;
  s.motion = "fast";
  s.dose_e = 20;
  s.frames = 4;
  SimHarness h(s, small_config());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const PoseEstimate& e = h.poses()[0];
  ASSERT_TRUE(e.searched);
  ASSERT_TRUE(e.state == TrackState::kTracking || e.state == TrackState::kUncertain) << to_string(e.state);
  const FrameRecord& r = h.records()[0];
  const hal::TargetTruth& seen = r.as_scanned;
  const std::int64_t span = h.limits().scan_time_ns(s.field_w, s.field_h, s.dwell_ns);
  // The beam reaches the target's row (y + 0.5) / field_h into the scan (flyback included).
  const double expected_ns = static_cast<double>(r.t_start_ns) + (seen.y_px + 0.5) / s.field_h * static_cast<double>(span);
  EXPECT_NEAR(static_cast<double>(e.t_beam_ns), expected_ns, 1.0e6) << "within 1 ms of when the beam passed it";
  // And the pose is where the target was then, not where it was at mid-scan.
  const double off_seen = std::hypot(e.x_px - seen.x_px, e.y_px - seen.y_px);
  const double off_mid = std::hypot(e.x_px - r.truth.x_px, e.y_px - r.truth.y_px);
  EXPECT_LT(off_seen, 1.5);
  EXPECT_GT(off_mid, 2.0 * off_seen) << "the scene moved enough during the field scan to tell the two apart";
  // An ROI frame, centred on the target: about mid-scan.
  const PoseEstimate& roi_pose = h.poses()[3];
  const std::int64_t mid = h.records()[3].t_start_ns + h.limits().scan_time_ns(h.next_rois()[2].w, h.next_rois()[2].h, s.dwell_ns) / 2;
  EXPECT_NEAR(static_cast<double>(roi_pose.t_beam_ns), static_cast<double>(mid), 1.0e6);
}

// A raster scan shows a target moving along x sheared: each row is scanned one row's time after
// the one above, the target further on. A shear is a turn by half its slope plus a stretch, and
// the rigid fit read the turn as the target's (noise-free, ±200 px/s, 50 µs rows: the needle tip
// +0.56° / −0.13°, the lamella on its post +0.24° / −0.28°). The scan-motion bias
// (scan_motion.hpp) is taken out of the pose: one direction and the other read the same angle.
TEST(Tracker, AMovingTargetsScanShearIsNotReadAsATurn) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    double mean_deg[2] = {};
    for (int k = 0; k < 2; ++k) {
      const double vx = k == 0 ? 300.0 : -300.0;
      Scenario s;
      s.target = target;
      s.motion = "static";
      s.noise = false;
      s.drift = false;
      s.frames = 30;
      s.edit_run = [vx](config::SimConfig& c) {
        auto& tr = c.targets[0].trajectory;
        tr = config::TrajectoryConfig{};
        tr.kind = "linear";
        tr.vx_px_s = vx;
        tr.margin_px = 110;
      };
      config::TrackerConfig tc = small_config();
      tc.correct_scan_motion = true;
      SimHarness h(s, tc);
      ASSERT_TRUE(h.status().ok) << h.status().message;
      h.run();
      double sum = 0;
      int n = 0;
      for (std::size_t f = 5; f < h.poses().size(); ++f) {
        const PoseEstimate& e = h.poses()[f];
        if (e.state != TrackState::kTracking || e.searched) continue;
        sum += std::fmod(e.meas_phi_deg - h.records()[f].as_scanned.phi_deg + 540.0, 360.0) - 180.0;
        ++n;
      }
      ASSERT_GE(n, 15) << target << " at " << vx << " px/s";
      mean_deg[k] = sum / n;
    }
    std::printf("%s: mean angle error %+.3f deg at +300 px/s, %+.3f deg at -300 px/s\n", target, mean_deg[0], mean_deg[1]);
    EXPECT_LT(std::fabs(mean_deg[0] - mean_deg[1]), 0.25) << target << ": the scan's shear read as a turn";
  }
}

// Charging: the detected signal's gain rising ×4 across the ROI (0.4 → 1.6, left to right).
// A ZNCC over the ramp pulls the pose towards the bright side (0.85 px in x on the needle tip at
// 20 e-/px, pose_envelope_probe --case charging_gradient); with the background plane as a
// nuisance of the sub-pixel fit (tracker.fit_background_plane, off by default) the bias is gone and
// the poses stay TRACKING (σ fitted with the same plane).
TEST(TrackerAccuracy, ChargingGradientAcrossTheRoiDoesNotPullThePose) {
  double bias[2] = {0, 0};
  double tracked[2] = {0, 0};
  for (int plane = 0; plane <= 1; ++plane) {
    Scenario s;
    s.target = "needle_tip";
    s.dose_e = 20;
    s.motion = "smooth";
    s.frames = 40;
    s.frame_fault = [](std::uint64_t, const hal::Roi& r, hal::Pixel* p, hal::Pixel m) {
      for (int y = 0; y < r.h; ++y)
        for (int x = 0; x < r.w; ++x) {
          hal::Pixel& q = p[static_cast<std::ptrdiff_t>(y) * r.w + x];
          q = static_cast<hal::Pixel>(std::min<double>(m, q * (0.4 + 1.2 * x / r.w)));
        }
    };
    config::TrackerConfig c = small_config();
    c.fit_background_plane = plane == 1;
    SimHarness h(s, c);
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const RunStats r = h.stats();
    ASSERT_GT(r.err_n, 20);
    bias[plane] = r.sum_dx / r.err_n;
    tracked[plane] = r.tracked_share();
    EXPECT_EQ(r.false_tracking, 0);
    std::printf("charging gradient, background plane %s: mean x error %+.2f px, TRACKING %.0f %%, RMS %.2f px\n",
                plane ? "on " : "off", bias[plane], 100 * tracked[plane], r.rms_px());
  }
  EXPECT_GT(bias[0], 0.5) << "without the plane the ramp pulls the pose to its bright side (the case measures that)";
  EXPECT_LT(std::fabs(bias[1]), 0.2);
  EXPECT_GE(tracked[1], tracked[0] - 0.05);
}
