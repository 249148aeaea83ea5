// No false TRACKING: a target that vanishes or was never in the field, pure noise, blank and
// saturated frames. The closed loop on the simulated SEM (real tracker, real renderer); every
// case prints its measured shares so a regression shows by how much.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "sempose/pose/loss_policy.hpp"
#include "sim_harness.hpp"

namespace pt = sempose::pose::testing;
using sempose::pose::TrackState;

namespace {

struct Counts {
  int tracking = 0, lost_streak_start = -1, tracking_after_gone = 0, first_lost_after_gone = -1;
};

sempose::config::TrackerConfig default_tracker() { return sempose::config::TrackerConfig{}; }

void print_case(const char* name, const pt::RunStats& r, int extra = -1) {
  std::printf("%-34s frames=%d tracked_share=%.3f%s\n", name, r.frames, r.tracked_share(),
              extra >= 0 ? (" frames_to_lost=" + std::to_string(extra)).c_str() : "");
}

}  // namespace

// A target tracked for 10 frames, then gone (only background left): LOST within a few frames
// and never TRACKING again on the background.
class Vanish : public ::testing::TestWithParam<std::tuple<std::string, double>> {};

TEST_P(Vanish, GoesLostAndStaysLost) {
  pt::Scenario s;
  s.target = std::get<0>(GetParam());
  s.dose_e = std::get<1>(GetParam());
  s.motion = "smooth";
  s.frames = 80;
  s.vanish_after = 10;
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const auto& poses = h.poses();
  // Followed while it is there: TRACKING, or UNCERTAIN (a near-symmetric target such as the
  // lamella on post at <= 2.5 e-/px is UNCERTAIN until its flip check settles, README: States).
  int tracked_before = 0;
  for (int f = 0; f < s.vanish_after; ++f)
    tracked_before += poses[f].state == TrackState::kTracking || poses[f].state == TrackState::kUncertain;
  EXPECT_GE(tracked_before, s.vanish_after - 1) << "the target must be followed while it is there";
  int first_not_tracking = -1, tracking_later = 0;
  for (int f = s.vanish_after; f < s.frames; ++f) {
    const bool tr = poses[static_cast<std::size_t>(f)].state == TrackState::kTracking;
    const bool followed = tr || poses[static_cast<std::size_t>(f)].state == TrackState::kUncertain;
    if (!followed && first_not_tracking < 0) first_not_tracking = f - s.vanish_after;
    if (tr && first_not_tracking >= 0) ++tracking_later;
  }
  std::printf("vanish %-12s dose %4.1f: followed before %d/%d, frames to LOST %d, TRACKING after that %d/%d\n",
              s.target.c_str(), s.dose_e, tracked_before, s.vanish_after, first_not_tracking, tracking_later,
              s.frames - s.vanish_after);
  ASSERT_GE(first_not_tracking, 0) << "never went LOST after the target vanished";
  EXPECT_LE(first_not_tracking, 3);
  EXPECT_EQ(tracking_later, 0) << "TRACKING on the background after the loss";
}

INSTANTIATE_TEST_SUITE_P(TargetsDoses, Vanish,
                         ::testing::Combine(::testing::Values("needle_tip", "lamella_post"),
                                            ::testing::Values(20.0, 6.0, 2.5, 1.0)));

// The target is nowhere in the field from the start: nothing may ever be TRACKING.
class NotInField : public ::testing::TestWithParam<std::tuple<std::string, double>> {};

TEST_P(NotInField, NeverTracking) {
  pt::Scenario s;
  s.target = std::get<0>(GetParam());
  s.dose_e = std::get<1>(GetParam());
  s.motion = "static";
  s.frames = 40;
  s.target_in_field = false;
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const pt::RunStats r = h.stats();
  print_case(("not in field " + s.target + " dose " + std::to_string(s.dose_e).substr(0, 4)).c_str(), r);
  // At 1 e-/px too (it was 1 frame in 40 before the UNCERTAIN state: a background match that
  // passed the search's tests, whose 180° alternative scored as well and whose poses then
  // wandered): whatever the search finds on background is never reported TRACKING.
  EXPECT_EQ(r.tracked, 0) << "TRACKING on the background of a field without the target";
  int uncertain = 0;
  for (const auto& e : h.poses()) uncertain += e.state == TrackState::kUncertain;
  std::printf("  UNCERTAIN %d of %d\n", uncertain, r.frames);
}

INSTANTIATE_TEST_SUITE_P(TargetsDoses, NotInField,
                         ::testing::Combine(::testing::Values("needle_tip", "lamella_post"),
                                            ::testing::Values(20.0, 6.0, 2.5, 1.0)));

// Pure noise (flat background, no target) at several doses, and blank and saturated frames.
TEST(NoFalseTracking, PureNoiseNeverTracking) {
  for (double dose : {20.0, 6.0, 1.0}) {
    pt::Scenario s;
    s.target = "needle_tip";
    s.dose_e = dose;
    s.motion = "static";
    s.frames = 40;
    s.background = false;
    s.target_in_field = false;
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const pt::RunStats r = h.stats();
    print_case(("pure noise dose " + std::to_string(dose).substr(0, 4)).c_str(), r);
    EXPECT_EQ(r.tracked, 0);
  }
}

TEST(NoFalseTracking, BlankAndSaturatedFramesNeverTracking) {
  for (auto kind : {pt::Scenario::Frames::kBlank, pt::Scenario::Frames::kSaturated}) {
    pt::Scenario s;
    s.target = "needle_tip";
    s.frames = 12;
    s.frames_kind = kind;
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const pt::RunStats r = h.stats();
    print_case(kind == pt::Scenario::Frames::kBlank ? "blank frames" : "saturated frames", r);
    EXPECT_EQ(r.tracked, 0);
    for (const auto& e : h.poses()) {
      EXPECT_TRUE(std::isfinite(e.x_px) && std::isfinite(e.y_px) && std::isfinite(e.phi_deg) && std::isfinite(e.score));
    }
  }
}

// The target really comes back: found again (the decision is not a latch).
TEST(NoFalseTracking, TargetThatReturnsIsFoundAgain) {
  pt::Scenario s;
  s.target = "needle_tip";
  s.dose_e = 6.0;
  s.motion = "jump";  // jumps every 0.5 s: lost and re-found
  s.frames = 120;
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const pt::RunStats r = h.stats();
  print_case("jumping target (re-found)", r);
  EXPECT_GE(r.tracked_share(), 0.95);
  // A frame scanned while the target jumps may give one pose off (README, known limitations).
  EXPECT_LE(r.false_tracking, 1);
}

// Scale is tracked (issue 13 items 2 and 6): the target's scale ramps ±25 % over the run
// (magnification / working distance). With a fixed-scale pattern 34–51 of 60 poses of such a
// ramp were reported TRACKING while > 3 px or > 10° off (the score sank slowly, so the
// recent-score test followed it down). Each case prints its tracked share and false count. (The procedural lamella's
// +25 % ramp at 2.5 e⁻/px still gives one false pose, while the scale is inside the rescaling
// dead band: README, Known limitations.)
class ScaleRamp : public ::testing::TestWithParam<std::tuple<std::string, double, double>> {};

TEST_P(ScaleRamp, TrackedWithoutFalsePoses) {
  pt::Scenario s;
  s.target = std::get<0>(GetParam());
  s.scale_to = std::get<1>(GetParam());
  s.dose_e = std::get<2>(GetParam());
  s.motion = "smooth";
  s.frames = 60;
  s.start_phi_deg = 30;
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  // The start search's frame and the three after it: a pose scoring below the explained
  // bound is UNCERTAIN there until the stream's pose noise is known (README: States).
  constexpr std::size_t kStartFrames = 4;
  int tracked = 0, false_n = 0, tracked_first_third = 0, tracked_after_start = 0;
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const auto& e = h.poses()[f];
    const auto& t = h.records()[f].truth;
    // The first third counts followed frames: a near-symmetric target (lamellae) is UNCERTAIN
    // for a few frames after its first search until the flip check settles (README: States);
    // that is not scale being rejected.
    if (3 * f < h.poses().size() && e.state == TrackState::kUncertain) ++tracked_first_third;
    if (e.state != TrackState::kTracking) continue;
    ++tracked;
    if (f >= kStartFrames) ++tracked_after_start;
    if (3 * f < h.poses().size()) ++tracked_first_third;
    const double dphi = pt::declared_angle_error_deg(e, t.phi_deg);
    if (!(std::hypot(e.x_px - t.x_px, e.y_px - t.y_px) <= 3.0 && dphi <= 10.0)) ++false_n;
  }
  std::printf("%-12s scale -> %.2f dose %4.1f: TRACKING %d/%d, false %d\n", s.target.c_str(), s.scale_to, s.dose_e,
              tracked, s.frames, false_n);
  EXPECT_EQ(false_n, 0) << "TRACKING while > 3 px or > 10 deg off";
  // Scale is tracked, not merely rejected: the whole ramp after the start stays TRACKING.
  EXPECT_GE(tracked_after_start, s.frames - static_cast<int>(kStartFrames) - 3);
  EXPECT_GE(tracked_first_third, s.frames / 3 - 1);
}

INSTANTIATE_TEST_SUITE_P(TargetsDoses, ScaleRamp,
                         ::testing::Values(std::make_tuple("needle_tip", 1.25, 2.5), std::make_tuple("needle_tip", 0.75, 6.0),
                                           std::make_tuple("lamella_post", 1.25, 6.0),
                                           std::make_tuple("lamella_post", 0.75, 2.5),
                                           std::make_tuple("lamella", 1.25, 6.0)));

namespace {
// TRACKING poses > 3 px or > 10° off the truth, TRACKING poses, full-field searches.
struct FalseCount {
  int tracked = 0, false_n = 0, searches = 0;
};
// Frame f of a "step" run was scanned while the target stepped (a torn frame): a step time lies
// between the ROI scan's start and end.
bool scanned_across_a_step(const pt::SimHarness& h, std::size_t f, double step_period_s) {
  const double t0 = 1e-9 * static_cast<double>(h.records()[f].t_start_ns - sempose::hal::SimSource::kVirtualEpochNs);
  const double t1 = 2.0 * h.records()[f].t_mid_s - t0;
  return std::floor(t0 / step_period_s) != std::floor(t1 / step_period_s);
}

FalseCount count_false(const pt::SimHarness& h) {
  FalseCount c;
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const auto& e = h.poses()[f];
    const auto& t = h.records()[f].truth;
    c.searches += e.searched;
    if (e.state != TrackState::kTracking) continue;
    ++c.tracked;
    const double dphi = pt::declared_angle_error_deg(e, t.phi_deg);
    if (!(std::hypot(e.x_px - t.x_px, e.y_px - t.y_px) <= 3.0 && dphi <= 10.0)) ++c.false_n;
  }
  return c;
}

// A simulated target started at 30° (as the accuracy bench's rows and pose_envelope_probe's
// cases are), its motion, dose and length.
pt::Scenario envelope_scene(const char* target, const char* motion, double dose, int frames) {
  pt::Scenario s;
  s.target = target;
  s.motion = motion;
  s.dose_e = dose;
  s.frames = frames;
  s.start_phi_deg = 30;
  return s;
}

// The scene's target moving on a straight line at (vx, vy) px/s from where it starts, bouncing
// when its centre comes margin_px from the field's edge (negative: beyond it).
void move_linearly(pt::Scenario& s, double vx, double vy, double margin_px) {
  s.edit_run = [=](sempose::config::SimConfig& sc) {
    auto& tr = sc.targets[0].trajectory;
    tr = sempose::config::TrajectoryConfig{};
    tr.kind = "linear";
    tr.vx_px_s = vx;
    tr.vy_px_s = vy;
    tr.margin_px = margin_px;
  };
}

// Runs a scene and prints its TRACKING, false and search counts under a label.
FalseCount run_and_count(pt::SimHarness& h, const std::string& label) {
  h.run();
  const FalseCount n = count_false(h);
  std::printf("%s: TRACKING %d/%zu, false %d, searches %d\n", label.c_str(), n.tracked, h.poses().size(), n.false_n,
              n.searches);
  return n;
}

// The tracked target drifting right slowly (100 px/s from x 220, 180 frames) and an untracked
// twin of it (pose_envelope_probe's second_target) starting at (x0, the target's y + dy) and
// moving at (vx, vy) px/s, free to leave the field.
pt::Scenario twin_scene(const char* target, double dose, double dy, double vx, double vy, double x0) {
  pt::Scenario s = envelope_scene(target, "static", dose, 180);
  s.start_x_px = 220;
  s.edit_run = [=](sempose::config::SimConfig& sc) {
    auto& a = sc.targets[0].trajectory;
    a = sempose::config::TrajectoryConfig{};
    a.kind = "linear";
    a.vx_px_s = 100;
    a.margin_px = 110;
    sempose::config::SimTargetConfig b = sc.targets[0];
    b.enabled = true;
    b.x_px = x0;
    b.y_px = sc.targets[0].y_px + dy;
    b.trajectory = sempose::config::TrajectoryConfig{};
    b.trajectory.kind = "linear";
    b.trajectory.vx_px_s = vx;
    b.trajectory.vy_px_s = vy;
    b.trajectory.margin_px = -200;
    sc.targets[1] = b;
  };
  return s;
}
}  // namespace

// The warped real crop spinning 450°/s (issue 13 item 6): the frame after the full-field
// search (a 77 ms scan, the target turned ~20°) has no angular rate in its prediction; the walk
// from the stale angle climbed a neighbouring maximum 16–18° and 11–16 px off that scored
// below the target's level but above every threshold, and its wrong velocity kept the track
// off for up to 17 frames (2 / 5 / 35 false poses at dose 20 / 6 / 2.5). The motion check
// searches such a pose again around the prediction and does not report it if it stays.
TEST(NoFalseTracking, FastSpinAfterTheStartSearch) {
  for (double dose : {20.0, 2.5}) {
    const pt::Scenario s = envelope_scene("warped", "spin", dose, 60);
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const FalseCount c = count_false(h);
    std::printf("warped spin dose %4.1f: TRACKING %d/%d, false %d, searches %d\n", dose, c.tracked, s.frames, c.false_n,
                c.searches);
    EXPECT_EQ(c.false_n, 0) << "TRACKING while > 3 px or > 10 deg off";
    // Of the 59 ROI frames after the search (whose own frame waits for them: UNCERTAIN), at most 2 not TRACKING.
    EXPECT_GE(c.tracked, s.frames - 1 - 2) << "the spin is followed, not rejected";
  }
}

// Gripper jaws opening and closing 8 px (issue 13 items 4 and 6): the rigid pattern drags the
// body's pose 3–6 px over several frames while its score sinks slowly. Such poses are not
// TRACKING (the pattern explains < 0.7 of the attainable score and the score is below the
// target's best level); the target is held in its ROI meanwhile (frames that also score far
// below its recent level still go to a full-field search, as after a jump), and it is
// TRACKING again when the jaws close.
TEST(NoFalseTracking, GripperJawsDoNotDragATrackedPose) {
  for (double dose : {20.0, 6.0}) {
    pt::Scenario s;
    s.target = "gripper";
    s.jaws = true;
    s.dose_e = dose;
    s.frames = 60;
    s.start_phi_deg = 30;
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const FalseCount c = count_false(h);
    std::printf("gripper jaws dose %4.1f: TRACKING %d/%d, false %d, searches %d\n", dose, c.tracked, s.frames, c.false_n,
                c.searches);
    EXPECT_EQ(c.false_n, 0) << "TRACKING while > 3 px or > 10 deg off";
    // At least 10 of 60 (12 / 12 before the parts check, States: parts moving apart; it keeps 2
    // more frames at 20 e-/px UNCERTAIN while the jaws are still apart, 10, and gives 2 back at
    // 6 e-/px, 14; the same rows of `pose_accuracy_bench --quick`).
    EXPECT_GE(c.tracked, s.frames / 6) << "tracked again whenever the jaws close";
  }
}

// Right after a start search the stream has shown nothing of the pose noise yet (it is known
// from the third innovation of ROI frames on), and a pose's own σ (the fit's curvature) does
// not see a neighbouring maximum. At 1 e-/px 10 of the 14 false poses over all dose-1 rows were
// there: the search frame or the three after it landing 4-12 px off (the warped real crop
// after its re-searches: a neighbouring maximum 9-12 px off that the walk keeps, at the
// target's score and with σ 0.9 px). A pose the pattern explains less well than the explained
// check's upper bound is therefore not TRACKING until the stream's pose noise is known.
TEST(NoFalseTracking, NotTrackingRightAfterASearchWhereTheStreamIsUnknown) {
  const sempose::config::TrackerConfig cfg = default_tracker();
  const double explained_bound = cfg.explained_threshold + sempose::pose::LossPolicy::kExplainedDoubt;
  pt::Scenario s;
  s.target = "warped";
  s.motion = "jump";
  s.dose_e = 1.0;
  s.frames = 60;
  s.start_phi_deg = 30;
  pt::SimHarness h(s, cfg);
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  int since_search = 1000, early_low_tracked = 0, early_low = 0;
  for (const auto& e : h.poses()) {
    since_search = e.searched ? 0 : since_search + 1;
    if (since_search <= 3 && e.score < explained_bound && e.state != TrackState::kLost &&
        e.state != TrackState::kAcquiring) {
      ++early_low;
      early_low_tracked += e.state == TrackState::kTracking;
    }
  }
  const FalseCount c = count_false(h);
  std::printf("warped jump dose 1: TRACKING %d/%d, false %d, searches %d; low-score poses <= 3 frames after a search: "
              "%d, TRACKING %d\n", c.tracked, s.frames, c.false_n, c.searches, early_low, early_low_tracked);
  EXPECT_GT(early_low, 0) << "the case must contain such poses, or it tests nothing";
  EXPECT_EQ(early_low_tracked, 0) << "TRACKING before the stream's pose noise is known";
  EXPECT_EQ(c.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (6 before the rule)";
}

// A torn frame (issue 13 item 6, `pose_accuracy_bench --full`, lamella on post jump@1.25 at
// 2.5 e-/px, frame 128): the target jumped 13 px while its ROI was scanned, so part of the ROI
// shows it at each place. The walk found the new place (0.657), the motion check's sweep around
// the old prediction scored 0.675 and replaced it: 12 px off, it was TRACKING. Two hypotheses
// more than 3 px apart whose scores differ by less than the score noise are rivals: the frame
// is followed but UNCERTAIN. The jump is still re-found at once (TRACKING < 1 px off within 2
// frames, as TrackingAgainWithinTwoFramesOfAJump asks).
TEST(NoFalseTracking, TornFrameDuringAJumpIsNotTracking) {
  pt::Scenario s;
  s.target = "lamella_post";
  s.motion = "jump";
  s.dose_e = 2.5;
  s.frames = 150;
  s.start_phi_deg = 30;
  s.scale_from = s.scale_to = 1.25;
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const FalseCount c = count_false(h);
  std::printf("lamella_post jump@1.25 dose 2.5, 150 frames: TRACKING %d/%d, false %d, searches %d\n", c.tracked, s.frames,
              c.false_n, c.searches);
  EXPECT_EQ(c.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (1 before the rival rule, frame 128)";
  EXPECT_GE(c.tracked, s.frames - 5) << "the rule costs the torn frames only";
}

// A spin past the recorded orientation (issue 13 item 6, `pose_accuracy_bench --full`,
// procedural lamella spin at 6 e-/px, frames 146-148): the bank's unrotated pattern (no
// interpolation) scores ~0.09 above its rotated neighbours where the target passes the
// orientation it was recorded at, and the walk, started at the predicted angle, stayed on that
// bump while the target turned on: 4 -> 9 -> 12 deg behind, the last one TRACKING at 0.62 (the
// spin's own score swing made it "confirmed"). A score below the target's recent level by more
// than the detector noise explains is now searched again around the prediction (the sweep).
TEST(NoFalseTracking, SpinPastTheRecordedOrientationIsFollowed) {
  pt::Scenario s;
  s.target = "lamella";
  s.motion = "spin";
  s.dose_e = 6.0;
  s.frames = 150;
  s.start_phi_deg = 30;
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const FalseCount c = count_false(h);
  double worst_deg = 0;
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const auto& e = h.poses()[f];
    if (e.state != TrackState::kTracking) continue;
    worst_deg = std::max(worst_deg, pt::declared_angle_error_deg(e, h.records()[f].truth.phi_deg));
  }
  std::printf("lamella spin dose 6, 150 frames: TRACKING %d/%d, false %d, worst TRACKING angle error %.2f deg\n", c.tracked,
              s.frames, c.false_n, worst_deg);
  EXPECT_EQ(c.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (1 before, frame 148: 11.6 deg behind)";
  EXPECT_GE(c.tracked, s.frames - 10) << "the spin is followed, not rejected (143/150 before)";
}

// A pattern filled with static clutter (README, Known limitations: look-alike background;
// heldout_end_to_end's needle recorded over a hole lattice): the needle tip at brightness 0.3
// recorded over a procedural background of contrast 0.3, still while the start search scans the
// field, then 10 px away. The clutter, which did not move, holds the first ROI frame's pose
// where the search found it (9 px off, σ ~0.3 px, score 0.71 after the search's 0.94): its own σ
// is all that judges it there (the stream's noise is not known yet), and it was TRACKING. Its
// score fell below the search's level by more than the target's confirmed margin and the
// detector's noise: UNCERTAIN. (The frames after it: StaticClutterHoldingThePoseIsNotTracking.)
TEST(NoFalseTracking, FirstRoiFrameWhoseScoreFellFromTheSearchIsNotTrusted) {
  pt::Scenario s;
  s.target = "needle_tip";
  s.motion = "step";
  s.step_x_px = 8;
  s.step_y_px = 6;
  s.step_period_s = 0.078;  // after the search's field scan (77.8 ms), before the first ROI frame
  s.background_contrast = 0.3;
  s.target_brightness = 0.3;
  s.dose_e = 20;
  s.frames = 3;
  s.start_phi_deg = 0;  // the pattern's recording pose
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const auto& e0 = h.poses()[0];
  const auto& e1 = h.poses()[1];
  const auto& t0 = h.records()[0].truth;
  const auto& t1 = h.records()[1].truth;
  const double err0 = std::hypot(e0.x_px - t0.x_px, e0.y_px - t0.y_px), err1 = std::hypot(e1.x_px - t1.x_px, e1.y_px - t1.y_px);
  std::printf("clutter step: search frame %s %.3f %.1f px; first ROI frame %s %.3f %.1f px (sigma %.2f px)\n",
              sempose::pose::to_string(e0.state), e0.score, err0, sempose::pose::to_string(e1.state), e1.score, err1,
              std::max(e1.sigma_x_px, e1.sigma_y_px));
  ASSERT_TRUE(e0.searched);
  EXPECT_LE(err0, 3.0) << "the target is still while the field is scanned";
  ASSERT_FALSE(e1.searched);
  EXPECT_GT(err1, 3.0) << "the case must hold the pose on the clutter, or it tests nothing";
  EXPECT_NE(e1.state, TrackState::kTracking) << "TRACKING " << err1 << " px off on its own sigma (it was before)";
}

// The same clutter over the frames after the first: the needle steps 10 px away and back every
// 78 ms (~8 ROI frames each way). Where the clutter outweighs the needle the pose stays at the
// recording spot while the needle is away, scoring ~0.71 against the 0.94 it had a frame before,
// σ ~0.15 px; it does not move, so its innovations and the stream's pose noise are ~0 and it was
// TRACKING ~9 px off on about half of the 60 frames (README Known limitations: 31 / 32 / 32 at
// 20 e-/px; C 0.5 B 0.3 at 6 e-/px 11). Its score fell by far more than the noise while the pose
// stood still: UNCERTAIN until the score is back. Each case must still hold the pose on the
// clutter (else it tests nothing) and still report the needle TRACKING when it is back there.
// The control, C 0.3 B 1 (the needle outweighs the clutter: the pose follows it, 0.97 -> 0.79 as
// the clutter is left behind), must stay TRACKING: a fall with a move is no doubt.
TEST(NoFalseTracking, StaticClutterHoldingThePoseIsNotTracking) {
  struct Case {
    double contrast, brightness, dose;
    bool clutter_wins;
  };
  const Case cases[] = {{0.3, 0.3, 20, true}, {0.5, 0.5, 20, true}, {0.5, 0.3, 20, true}, {0.5, 0.3, 6, true}, {0.3, 1.0, 20, false}};
  for (const Case& c : cases) {
    pt::Scenario s;
    s.target = "needle_tip";
    s.motion = "step";
    s.step_x_px = 8;
    s.step_y_px = 6;
    s.step_period_s = 0.078;
    s.background_contrast = c.contrast;
    s.target_brightness = c.brightness;
    s.dose_e = c.dose;
    s.frames = 60;
    s.start_phi_deg = 0;
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    int tracking = 0, false_tracking = 0, false_torn = 0, held_off = 0, tracking_near = 0, torn_n = 0, tracking_torn = 0;
    for (std::size_t f = 0; f < h.poses().size(); ++f) {
      const auto& e = h.poses()[f];
      const auto& t = h.records()[f].truth;
      // A torn frame: the needle stepped while its ROI was scanned (half the ROI shows it at
      // each place; frame 39 of every row, Known limitations), told by the step times.
      const bool torn = scanned_across_a_step(h, f, s.step_period_s);
      const double err = std::hypot(e.x_px - t.x_px, e.y_px - t.y_px);
      const double err_deg = pt::declared_angle_error_deg(e, t.phi_deg);
      const bool off = err > sempose::pose::LossPolicy::kFalsePx || err_deg > sempose::pose::LossPolicy::kFalseDeg;
      const bool followed = e.state == TrackState::kTracking || e.state == TrackState::kUncertain;
      held_off += followed && off && !e.searched;
      torn_n += torn;
      if (e.state != TrackState::kTracking) continue;
      ++tracking;
      tracking_torn += torn;
      false_tracking += off;
      false_torn += off && torn;
      tracking_near += !off;
    }
    std::printf("clutter C %.2g B %.2g dose %4.1f: TRACKING %d/60 (%d of the %d torn frames), false %d (%d on a torn frame), "
                "followed off the needle %d\n",
                c.contrast, c.brightness, c.dose, tracking, tracking_torn, torn_n, false_tracking, false_torn, held_off);
    if (c.clutter_wins) {
      EXPECT_GE(held_off, 10) << "the case must hold the pose on the clutter, or it tests nothing";
      EXPECT_EQ(false_tracking, 0) << "TRACKING on the clutter while the needle is away";
      EXPECT_GE(tracking_near, 10) << "the needle back at the recording spot is TRACKING again";
    } else {
      EXPECT_LE(held_off, 1) << "the control's pose follows the needle";
      // Its torn frame scores as the frames before it (0.80 after 0.79, still): nothing tells it.
      EXPECT_EQ(false_tracking - false_torn, 0);
      // 55 before the scale's σ judged the pose (Tracker::Impl::judge_scale_sigma): the needle
      // stepping 10 px against the clutter standing in its window pulls the scale's σ above 2.5x
      // its level on 6 whole frames, now UNCERTAIN (49). The price of that rule, measured here.
      EXPECT_GE(tracking, 48) << "a score that fell with a move is no doubt: the needle followed is TRACKING";
    }
  }
}

// heldout_end_to_end's look-alike rows in the simulator: the needle tip recorded over static
// clutter that outweighs it (C 0.5 B 0.3) at the field's centre, but standing 5 px from that
// spot when the start search scans the field. The clutter, which did not move, pulls the search
// frame's pose to the recording spot (4.2 px off, score 0.88); nothing on that one frame tells
// it from a true search frame (its σ is not measured, its score is high), so a first start's
// search frame is not TRACKING until an ROI frame confirms it (README: States). It was TRACKING
// before. The control, the needle on the recording spot, is confirmed by the frames after it.
// (A needle that then stays 5 px from the spot keeps the pose on the clutter, TRACKING: Known
// limitations, look-alike background; the held-out rows' needle moves on and is not.)
TEST(NoFalseTracking, FirstSearchFrameHeldByStaticClutterIsNotTracking) {
  for (const bool on_spot : {false, true}) {
    pt::Scenario s;
    s.target = "needle_tip";
    s.motion = "static";
    s.start_x_px = on_spot ? 320 : 324;  // the pattern is recorded at the field's centre (320, 240)
    s.start_y_px = on_spot ? 240 : 243;
    s.background_contrast = 0.5;
    s.target_brightness = 0.3;
    s.dose_e = 20;
    s.frames = on_spot ? 10 : 1;
    s.start_phi_deg = 0;
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    int tracking = 0;
    for (const auto& e : h.poses()) tracking += e.state == TrackState::kTracking;
    const auto& e0 = h.poses()[0];
    const auto& t0 = h.records()[0].truth;
    const double err0 = std::hypot(e0.x_px - t0.x_px, e0.y_px - t0.y_px);
    std::printf("clutter C 0.5 B 0.3, needle %s the recording spot: search frame %s %.3f %.1f px; TRACKING %d/%d\n",
                on_spot ? "on" : "5 px from", sempose::pose::to_string(e0.state), e0.score, err0, tracking, s.frames);
    ASSERT_TRUE(e0.searched);
    EXPECT_NE(e0.state, TrackState::kTracking) << "a first start's search frame waits for an ROI frame to confirm it";
    if (on_spot) {
      EXPECT_LE(err0, 1.0);
      EXPECT_GE(tracking, 8) << "the frames after the search confirm a true pose";
    } else {
      EXPECT_GT(err0, 3.0) << "the clutter must hold the search's pose at the recording spot, or the case tests nothing";
    }
  }
}

namespace {

// The needle stepping (8, 6) px every 78 ms over procedural clutter of contrast C, brightness 1
// (pose_accuracy_bench --clutter's control rows), 60 frames.
pt::Scenario torn_step_scene(double contrast, double dose, double start_phi_deg) {
  pt::Scenario s;
  s.target = "needle_tip";
  s.motion = "step";
  s.step_x_px = 8;
  s.step_y_px = 6;
  s.step_period_s = 0.078;
  s.background_contrast = contrast;
  s.target_brightness = 1.0;
  s.dose_e = dose;
  s.frames = 60;
  s.start_phi_deg = start_phi_deg;
  return s;
}

// A run's frames split into torn ones (a step between the scan's start and end) and whole ones.
struct TornTally {
  int torn_n = 0, torn_off = 0, torn_off_tracking = 0;
  int whole_n = 0, whole_tracking = 0, whole_false = 0, whole_split = 0;
};

TornTally tally_torn_frames(const pt::SimHarness& h, const pt::Scenario& s) {
  TornTally c;
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const auto& e = h.poses()[f];
    const auto& t = h.records()[f].truth;
    const bool torn = scanned_across_a_step(h, f, s.step_period_s);
    const double off_px = std::hypot(e.x_px - t.x_px, e.y_px - t.y_px);
    const bool off = off_px > sempose::pose::LossPolicy::kFalsePx ||
                     pt::declared_angle_error_deg(e, t.phi_deg) > sempose::pose::LossPolicy::kFalseDeg;
    const bool tracking = e.state == TrackState::kTracking;
    if (torn) {
      ++c.torn_n;
      c.torn_off += off && !e.searched;
      c.torn_off_tracking += off && tracking;
      if (off && !e.searched) {
        std::printf("torn frame %zu: %.1f px off, state %d, reasons %d\n", f, off_px, static_cast<int>(e.state),
                    static_cast<int>(e.reason_bits));
      }
    } else if (!e.searched) {
      ++c.whole_n;
      c.whole_tracking += tracking;
      c.whole_false += off && tracking;
      // The split check's verdict (UNCERTAIN with reason 128) on a whole frame.
      c.whole_split += e.state == TrackState::kUncertain && (e.reason_bits & 128) != 0;
    }
  }
  std::printf("torn step C %.2g B 1 dose %4.1f: torn frames %d (%d off the needle, %d of them TRACKING); whole frames %d, "
              "TRACKING %d, false %d, split-check UNCERTAIN %d\n",
              s.background_contrast, s.dose_e, c.torn_n, c.torn_off, c.torn_off_tracking, c.whole_n, c.whole_tracking,
              c.whole_false, c.whole_split);
  return c;
}

}  // namespace

// A torn frame (issue 13 item 6): the needle steps 10 px while its ROI is scanned, so the lines
// scanned before the step show it at one place and those after at the other. In the clutter
// control cases (the needle outweighs the clutter: the pose follows it) frame 39 was TRACKING
// 7-8.6 px off at 0.76-0.86 (`pose_accuracy_bench --clutter`: 4 false TRACKING in these four
// cases): its score is at the level of the frames before, so neither the score rules nor the
// fall-while-still rule see it. The split-scan check (Tracker torn(), split_consistency.hpp: on
// a target the stream says stood still, the rows scanned first and those scanned last fitted
// apart, their displacements differing by more than their noise and by at least kTornApartPx)
// makes it UNCERTAIN at 20 e-/px. At 6 e-/px the parts' noise hides it (C 0.12: 2.9 SD where
// the check asks 3.4; C 0.3: the stream's pose noise does not let the target count as still;
// README Known limitations in depth): those cases only check that the whole frames stay
// TRACKING. Whole frames of every case must stay TRACKING (so the check cannot pass by refusing
// everything): at most 3 of them lost per case.
TEST(NoFalseTracking, TornFrameOfAStepIsNotTracking) {
  struct Case {
    double contrast, dose;
    bool torn_caught;
  };
  const Case cases[] = {{0.12, 20, true}, {0.3, 20, true}, {0.12, 6, false}, {0.3, 6, false}};
  for (const Case& c : cases) {
    // Started at 30° (the bench's clutter rows start at 0°: the next test).
    const pt::Scenario s = torn_step_scene(c.contrast, c.dose, 30);
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const TornTally t = tally_torn_frames(h, s);
    EXPECT_GT(t.torn_n, 0) << "the case must contain a torn frame, or it tests nothing";
    if (c.torn_caught) {
      EXPECT_GT(t.torn_off, 0) << "the case must contain a torn frame off the needle, or it tests nothing";
      EXPECT_EQ(t.torn_off_tracking, 0) << "a torn frame TRACKING off the needle (frame 39 before the split check)";
    }
    EXPECT_EQ(t.whole_false, 0);
    EXPECT_GE(t.whole_tracking, t.whole_n - 3) << "whole frames of the same scene must stay TRACKING";
  }
}

// The clutter control row C 0.3 B 1 at 6 e-/px (pose_accuracy_bench --clutter): its torn frame
// (frame 39, 8.6 px off) was TRACKING because the split check's still gate stayed closed — the
// last two poses turned 2.3° and the tracked scale stepped 0.27 %, both the stream's noise at
// this dose on a needle that stood still. With the gate judged against the stream's own pose
// noise in angle and the scale's running rate, the torn frame is UNCERTAIN and the whole frames
// of the same scene at the same dose stay TRACKING (no more than 3 lost, as at 20 e-/px, before
// the blur rule; no more than 8 since). The blur rule (Tracker::Impl::widen_for_blur) widens σ
// at the needle's second place: there the recorded clutter is not under it, the fit is flatter
// (sharpness 1/2.4-1/3.2 against 1/1.15 at the first place, score 0.74 against 0.92) and the
// poses are 0.1-2.6 px off with σ 0.25-0.45 px (RMS(error/σ) ~2 per axis; ~0.8 widened): 4 more
// whole frames there (36, 49, 50, 53; 0.2-0.8 px off) are UNCERTAIN on the widened σ (49 → 45
// of 52 TRACKING; frames 1, 18, 19 were UNCERTAIN by other rules before).
TEST(NoFalseTracking, TornFrameOfAStepAtSixElectronsIsNotTracking) {
  // Started at 0°, as pose_accuracy_bench --clutter's rows are.
  const pt::Scenario s = torn_step_scene(0.3, 6, 0);
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const TornTally t = tally_torn_frames(h, s);
  ASSERT_GT(t.torn_off, 0) << "the case must contain a torn frame off the needle, or it tests nothing";
  EXPECT_EQ(t.torn_off_tracking, 0) << "a torn frame TRACKING off the needle at 6 e-/px (frame 39 before the noise-aware still gate)";
  EXPECT_EQ(t.whole_false, 0);
  EXPECT_EQ(t.whole_split, 0) << "a whole frame turned UNCERTAIN by the split check";
  EXPECT_GE(t.whole_tracking, t.whole_n - 8) << "whole frames of the same scene at the same dose must stay TRACKING";
}

// A magnification change without SELECT (issue 13 item 2; pose_envelope_probe scale_step_*):
// the target, tracked at its pattern's size, steps to 1.2× (or 1/1.2×) mid-run. The frame after
// the step is unexplained and the target is lost; the search that re-found it looked only at the
// last tracked scale and took the best match of the old size, a wrong pose that the frames after
// it kept: the needle tip 10-11 px off, the lamella on post 24-28 px and 87° off, TRACKING at
// 0.66-0.70 (s/a ~0.7, the explained check's bound; its level forgotten with the loss) on 21 and
// 34 of 80 frames at 6 e-/px. Searched over the scale levels around the last tracked scale, it is
// re-found at its new size in one search. And the size the search found is the continuity line's
// from then on (ContinuityAnchor::resized): the procedural lamella stepped down at 20 e-/px, lost
// through held frames and re-found on the line at 0.83, was held UNCERTAIN to the end by the line's
// size check (90 -> 37.5 % TRACKING) without it.
TEST(NoFalseTracking, MagnificationStepWithoutSelectIsFoundAtTheNewSize) {
  struct Case {
    const char* target;
    double to, dose;
  };
  for (const Case& c : {Case{"needle_tip", 1.2, 6}, Case{"lamella_post", 1.2, 6}, Case{"needle_tip", 1.0 / 1.2, 6},
                        Case{"lamella", 1.0 / 1.2, 20}}) {
    pt::Scenario s = envelope_scene(c.target, "smooth", c.dose, 80);
    const double to = c.to;
    s.edit_run = [to](sempose::config::SimConfig& sc) {
      sc.targets[0].scale.from = 1.0;
      sc.targets[0].scale.to = to;
      sc.targets[0].scale.start_s = 0.4;  // ~frame 33, a step (no ramp)
    };
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, std::string(c.target) + " scale step to " + std::to_string(c.to) + " dose " + std::to_string(c.dose));
    EXPECT_EQ(n.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (21 / 34 / 11 before)";
    EXPECT_GE(n.tracked, s.frames - 8) << "re-found at its new size and tracked again";
  }
}

// A target leaving the field across its edge and coming back (pose_envelope_probe leave_*): it
// moves left 3 px a frame until its centre is on the field's edge, then back. The pattern's window
// cannot be placed beyond the field, so the search that re-finds it there puts the pose where the
// window touches the edge: the needle tip 4.2 px off, TRACKING; the lamella on post's search took
// the 180° look-alike that the visible half matched better, and its flip check, settled by the
// last tracked angle, never looked again: 103 frames TRACKING 14-16 px and 180° off after the
// target was back in the field. A pose whose window reaches the edge is UNCERTAIN, and a search
// there leaves the flip check open for the frames after it to decide.
TEST(NoFalseTracking, TargetLeavingTheFieldAcrossAnEdgeIsNotTrackedAtTheEdge) {
  struct Case {
    const char* target;
    double dose;
  };
  for (const Case& c : {Case{"needle_tip", 6}, Case{"lamella_post", 20}}) {
    pt::Scenario s = envelope_scene(c.target, "static", c.dose, 150);
    s.start_x_px = 200;
    move_linearly(s, -300, 0, 0);  // bounces when its centre reaches the edge
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, std::string(c.target) + " leaving across the edge, dose " + std::to_string(c.dose));
    EXPECT_EQ(n.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (1 / 103 before)";
    EXPECT_GE(n.tracked, s.frames * 4 / 5) << "tracked while its pattern fits in the field";
  }
}

// tracker.filter tuned loosely within its ranges (meas_sigma_px 100; a tiny jerk with gate_sigma
// 1000): the filtered pose, the one reported, lagged the target by 120-224 px on a straight line
// while every pose was TRACKING on its measurement (hostile round 13). The filter restarts
// beyond the false-pose distance from the measurement, and a filtered pose more than half that
// away is UNCERTAIN.
TEST(NoFalseTracking, AFilterThatCannotFollowIsNotReportedTracking) {
  for (int tuning = 0; tuning < 2; ++tuning) {
    pt::Scenario s = envelope_scene("needle_tip", "fast", 6.0, 80);
    sempose::config::TrackerConfig tc = default_tracker();
    tc.filter.enabled = true;
    if (tuning == 0) {
      tc.filter.meas_sigma_px = 100;
      tc.filter.meas_sigma_deg = 180;
    } else {
      tc.filter.jerk_px_s3 = tc.filter.jerk_deg_s3 = 0.001;
      tc.filter.adapt_jerk = false;
      tc.filter.gate_sigma = 1000;
    }
    pt::SimHarness h(s, tc);
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, tuning == 0 ? "filter meas_sigma_px 100" : "filter tiny jerk, gate 1000");
    EXPECT_EQ(n.false_n, 0) << "a lagging filtered pose reported TRACKING";
    EXPECT_GE(n.tracked, s.frames / 2) << "the target is still followed";
  }
}

// The same through a corner at 1 e-/px (pose_envelope_probe leave_corner_whole): the lamella on
// its post came back into the field and the search took its 180° look-alike 16 px off, scoring
// 0.50 against the target's 0.52 (one score difference's noise beats the search's tie-break
// there). The last tracked angle was taken to have chosen, so the flip check stayed shut, and 3
// of the ~30 poses followed on the look-alike were TRACKING 15-17 px and 178° off. A winner
// turned from the last angle opens the check; the frames after it settle on the target.
TEST(NoFalseTracking, ASearchWinnerTurnedFromTheLastAngleOpensTheFlipCheck) {
  pt::Scenario s = envelope_scene("lamella_post", "static", 1.0, 250);
  s.start_x_px = 200;
  s.start_y_px = 180;
  move_linearly(s, -300, -285, -170);  // bounces once the whole target has left through the corner
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post leaving through the corner, dose 1");
  EXPECT_EQ(n.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (3 before)";
  EXPECT_GE(n.tracked, 40) << "followed again once back in the field (31 TRACKING before, on the look-alike too)";
}

// The target's size leaving the scales the tracker follows (0.7-1.45: beyond, the ROI cannot hold
// the pattern; pose_envelope_probe scale_ramp_*): a ramp from 1 to 1.6 or 0.6 over the run. The
// tracked scale stops at the range's end while the target grows or shrinks on, and the pose drifts
// with the mismatch: the needle tip 3-6 px off from truth 1.51 / 0.65 on, TRACKING on 10 / 7 of
// 100 frames at 6 e-/px. A frame whose reading lies beyond the end the tracked scale is pinned at
// is UNCERTAIN; the ramp inside the range stays TRACKING.
TEST(NoFalseTracking, ScaleBeyondTheTrackedRangeIsNotTracking) {
  for (const double to : {1.6, 0.6}) {
    pt::Scenario s = envelope_scene("needle_tip", "smooth", 6, 100);
    s.scale_to = to;
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, "needle_tip scale ramp to " + std::to_string(to) + " dose 6");
    int tracked_in_range = 0;  // TRACKING while the truth is inside 0.7-1.45 by 2 %
    for (std::size_t f = 0; f < h.poses().size(); ++f) {
      const double truth = h.records()[f].truth.scale;
      tracked_in_range += h.poses()[f].state == TrackState::kTracking && truth > 0.7 * 1.02 && truth < 1.45 / 1.02;
    }
    std::printf("  TRACKING inside the range %d\n", tracked_in_range);
    EXPECT_EQ(n.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (10 / 7 before)";
    EXPECT_GE(tracked_in_range, 55) << "the ramp inside the tracked range stays TRACKING";
  }
}

// A user's shape mask (targets[].pattern_sets[].mask; here the simulator's outline, alpha 0.5)
// keeps the target's own pixels and cuts a flat target's rim in half: what tells the lamella on
// its post from itself turned by 180° lies largely outside the mask. At 2.5 e-/px the masked
// score preferred the pose turned ~180° and 16-20 px off (0.60-0.62 against the target's
// 0.52-0.60): the search took it, the flip check kept it, and 52 of 60 poses of
// `pose_accuracy_bench --quick --mask outline` were false TRACKING from the fifth frame on. The
// flip check now also needs the whole circle's binned scores to agree; at 20 e-/px they do.
TEST(NoFalseTracking, ShapeMaskOnTheLamellaOnItsPostDoesNotKeepTheFlippedPose) {
  for (double dose : {2.5, 20.0}) {
    pt::Scenario s = envelope_scene("lamella_post", "smooth", dose, 12);
    s.shape_mask = true;
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const FalseCount c = count_false(h);
    std::printf("lamella_post outline mask dose %4.1f: TRACKING %d/%d, false %d, searches %d\n", dose, c.tracked, s.frames,
                c.false_n, c.searches);
    EXPECT_EQ(c.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (7 of 12 on the base at 2.5 e-/px)";
    if (dose >= 20) {
      EXPECT_GE(c.tracked, s.frames / 2) << "the masked target is still tracked where its scores tell it";
    }
  }
}

// A target turned by 180° between two frames (pose_envelope_probe turn_180) whose pattern is only
// partly symmetric: the lamella on its post (declared order 1, its post breaks the symmetry)
// turned 180° shows its body where the pattern's body was, 15-17 px from the true place. At 2.5
// e-/px the walk from the predicted angle took that look-alike (0.645-0.68; the target's level
// 0.72) and, once the motion model had learnt the jump, reported it TRACKING on 14 frames (1 at
// 20 and at 6 e-/px). Not physics: the true hypothesis scores 0.705-0.737 in the same frames, a
// lead of 0.05-0.06 a frame, under one frame's noise of a difference of two scores (0.068) but
// steady. The jump opens the flip check, whose paired differences settle on the target in 4
// frames. Fails on the base (14 and 1 false).
TEST(NoFalseTracking, TargetTurnedHalfRoundIsNotTrackedOnItsTurnedLookAlike) {
  for (double dose : {2.5, 20.0}) {
    pt::Scenario s;
    s.target = "lamella_post";
    s.dose_e = dose;
    s.frames = 100;
    s.start_phi_deg = 30;
    s.motion = "static";
    s.edit_run = [](sempose::config::SimConfig& c) {
      auto& tr = c.targets[0].trajectory;
      tr = sempose::config::TrajectoryConfig{};
      tr.kind = "steps";  // turns by 180° at 0.4 s (frame 33) and back at 0.8 s
      tr.steps = 1;
      tr.period_s = 0.4;
      tr.amplitude_phi_deg = 180;
    };
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    ASSERT_EQ(h.tracker()->symmetry(0).order, 1) << "the post breaks the lamella's symmetry";
    const FalseCount n = run_and_count(h, "lamella_post turned by 180 deg, dose " + std::to_string(dose));
    EXPECT_EQ(n.false_n, 0) << "TRACKING on the turned look-alike (14 at 2.5 e-/px, 1 at 20 on the base)";
    EXPECT_GE(n.tracked, s.frames * 4 / 5) << "the target itself is tracked again once the flip is settled";
  }
}

// The lamella on its post spinning 45° a frame (pose_envelope_probe spin_45deg_per_frame): the
// walk cannot follow it, the frames are held or lost, and its angle is free when the pose is
// followed again. The post breaks the lamella's symmetry only partly: turned 180° about a point
// 8 px off its centre the pattern fits it nearly as well, and at 6 e-/px the pose was followed
// again on that look-alike, 16 px and 171-180° off at 0.72-0.78 while the target scored
// 0.79-0.82, TRACKING on 7 frames. A pose followed again after a hold or a loss is TRACKING only
// when it leads its 180° opposite (judge_against_opposite). Fails on the base (7 false).
TEST(NoFalseTracking, PoseFollowedAgainAfterALossIsNotTheTurnedLookAlike) {
  for (double dose : {6.0, 2.5}) {
    pt::Scenario s = envelope_scene("lamella_post", "spin", dose, 80);
    s.edit_run = [](sempose::config::SimConfig& sc) { sc.targets[0].trajectory.omega_deg_s = 45.0 / 0.0101; };
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    ASSERT_EQ(h.tracker()->symmetry(0).order, 1) << "the post breaks the lamella's symmetry";
    const FalseCount n = run_and_count(h, "lamella_post spinning 45 deg a frame, dose " + std::to_string(dose));
    // The look-alike is > 3 px off and turned ~180°. (The target turns ~40° while its ROI is
    // scanned, and a pose on it can read up to ~10° off, its walk at its step bound: counted by
    // run_and_count, not asserted here.)
    int turned = 0;
    for (std::size_t f = 0; f < h.poses().size(); ++f) {
      const auto& e = h.poses()[f];
      const auto& t = h.records()[f].truth;
      if (e.state == TrackState::kTracking &&
          (std::hypot(e.x_px - t.x_px, e.y_px - t.y_px) > 3.0 || pt::declared_angle_error_deg(e, t.phi_deg) > 90.0))
        ++turned;
    }
    EXPECT_EQ(turned, 0) << "TRACKING on the turned look-alike (7 at 6 e-/px on the base)";
    EXPECT_GE(n.tracked, 20) << "the target itself is still reported TRACKING on some frames";
  }
}

// The lamella on its post spinning 15° a frame at 20 e-/px (pose_envelope_probe
// spin_15deg_per_frame): the frame after the first TRACKING pose (0.93) followed a turned
// neighbour 16 px and 82° off at 0.70, UNCERTAIN; the next took that one's 180° turned copy,
// 15 px and 175° off at 0.78, TRACKING (the opposite check had ended on the first pose). A pose
// followed below the target's own level and not reported opens that check again.
TEST(NoFalseTracking, PoseFollowedBelowTheTargetsLevelIsNotTheTurnedLookAlikeNext) {
  pt::Scenario s = envelope_scene("lamella_post", "spin", 20.0, 80);
  s.edit_run = [](sempose::config::SimConfig& sc) { sc.targets[0].trajectory.omega_deg_s = 15.0 / 0.0101; };
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post spinning 15 deg a frame, dose 20");
  EXPECT_EQ(n.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (1, 175 deg off, before)";
  EXPECT_GE(n.tracked, 60) << "the spin is followed once found (68 of 80 frames TRACKING)";
}

// A second, untracked object of the same pattern passing 30 px from the tracked target (issue 13:
// several targets; pose_envelope_probe twin_passes_30px): as the two overlap the score falls and
// the tracker holds, the merged image drags the followed pose onto the twin, which then scores at
// the target's level and moves smoothly: the lamella on post TRACKING on the twin up to 214 px off
// (51 poses at 6 e-/px), the needle tip 3 poses up to 39 px off. After a held frame a pose is
// TRACKING again only where the last TRACKING poses' motion leads (continuity_anchor.hpp).
TEST(NoFalseTracking, TwinOfThePatternPassingByDoesNotCarryThePoseAway) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    const pt::Scenario s = twin_scene(target, 6, 30, -300, 0, 760);  // the twin enters from the right, 3x faster
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, std::string(target) + " with a twin passing 30 px away, dose 6");
    EXPECT_EQ(n.false_n, 0) << "TRACKING on the twin (3 / 51 before)";
    EXPECT_GE(n.tracked, s.frames / 2) << "tracked before the twin passes";
  }
}

// The same twin passing 70 px below the lamella on its post (pose_envelope_probe twin_passes_70px,
// 6 e-/px): its body entering the window drew the pose up over 4 UNCERTAIN frames, then 2 poses
// 13 px off were TRACKING at χ² 4.1-4.5 (the target's level 2.5): significant, but their scores
// kept 0.86 of what the target reaches there, more than a pose 3 px off keeps, so judge_fit's
// material test passed them (1479eab). After a doubted pose such a fit is TRACKING only on the
// continuity line (Tracker::Impl::keep_continuity).
TEST(NoFalseTracking, TwinBelowTheTargetDoesNotDragAPoseBackToTracking) {
  const pt::Scenario s = twin_scene("lamella_post", 6, 70, -300, 0, 760);
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post with a twin passing 70 px below, dose 6");
  EXPECT_EQ(n.false_n, 0) << "TRACKING while dragged by the twin (2 before)";
  EXPECT_GE(n.tracked, 0.75 * s.frames) << "tracked before, while and after the twin passes (88.9 % before)";
}

// The same twin passing over the lamella on post at twice the speed (pose_envelope_probe
// twin_passes_over_fast): the target is covered, held and lost, and the search after the loss
// finds the merged image 14 px off, on the twin; it forgot the line, so the poses followed the
// twin out of the field, TRACKING up to 266 px off (32 / 31 a row at 6 / 2.5 e-/px on 1703905).
// The line's own place, measured in that search frame, scores with the winner: the winner is a
// rival (UNCERTAIN) and the line stays to judge the poses after it (Tracker::rival_on_line).
TEST(NoFalseTracking, TwinPassingOverFastDoesNotTakeThePoseAway) {
  const double dose = 6.0;
  const pt::Scenario s = twin_scene("lamella_post", dose, 0, -600, 0, 760);  // the twin runs over it, 6x faster
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post with a twin passing over fast, dose " + std::to_string(dose));
  EXPECT_EQ(n.false_n, 0) << "TRACKING on the twin (32 before)";
  EXPECT_GE(n.tracked, s.frames / 2) << "tracked before the twin passes and after it left";
}

// A twin crossing over the lamella on post at 45° (pose_envelope_probe twin_crosses_over_at_45deg):
// covered, the target was lost and re-found 78 px off on a 180°-turned look-alike of the merged
// image, then followed onto its own 180° look-alike 15 px off and kept there: TRACKING 180° off on
// 108 / 110 of 180 frames at 20 / 6 e-/px on 1703905. A re-acquisition off the line, turned from it
// and below its level keeps the line (Tracker::turned_off_line; the line checks the angle too), and
// a pose turned from the open line measures its opposite: the target is taken back once the twin
// has passed.
TEST(NoFalseTracking, TwinCrossingOverDoesNotLeaveThePoseTurned) {
  const double dose = 6.0;
  const pt::Scenario s = twin_scene("lamella_post", dose, 270, -300, -300, 580);  // the twin crosses its path at 45°
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post with a twin crossing over at 45 deg, dose " + std::to_string(dose));
  EXPECT_EQ(n.false_n, 0) << "TRACKING on a turned look-alike (110 before)";
  int tracked_at_end = 0;  // the twin has left: the target itself tracked again
  for (std::size_t f = 150; f < h.poses().size(); ++f) tracked_at_end += h.poses()[f].state == TrackState::kTracking;
  EXPECT_GE(n.tracked, s.frames / 3) << "tracked before the twin and after it";
  EXPECT_GE(tracked_at_end, 25) << "the target taken back once the twin has passed";
}

// A twin crossing the target's path at the target's level (pose_envelope_probe
// twin_crosses_down_at_45deg, twin_crosses_over_at_90deg): the pose jumped onto the twin 30-35 px
// away in one ROI frame (a surprising pose the score "confirmed", so the motion check never measured
// the predicted place, which held the target at its level too) and followed it, TRACKING up to
// 282 px off (fc3265b: the lamella on post crossed from above 61 of 180 at 20 e-/px, the needle tip
// crossed at 90° 43). The jump is declined while the predicted place holds the target's level
// (Tracker::declines_jump), UNCERTAIN, and the continuity check opens.
TEST(NoFalseTracking, TwinCrossingAtTheTargetsLevelDoesNotTakeThePoseAlong) {
  struct Row {
    const char* target;
    double dy, vx, vy, x0;
    int before;
  };
  for (const Row& r : {Row{"lamella_post", -230, -300, 300, 530, 61}, Row{"needle_tip", 270, 0, -300, 310, 43}}) {
    const pt::Scenario s = twin_scene(r.target, 20, r.dy, r.vx, r.vy, r.x0);
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, std::string(r.target) + " with a twin crossing its path, dose 20");
    EXPECT_EQ(n.false_n, 0) << r.target << ": TRACKING on the twin (" << r.before << " before)";
    EXPECT_GE(n.tracked, s.frames / 4) << r.target << ": tracked before the twin came";
  }
}

// The same twin coming down at 45° onto the procedural lamella (pose_envelope_probe
// twin_crosses_down_at_45deg, 20 e-/px): its body in the window drew the scale 1.00 -> 1.13 and
// the pose along, 9 TRACKING poses 3-7.8 px off at scores and χ² near the target's level, while
// the scale's σ grew from the target's 0.005 to 0.010-0.022 (Tracker::Impl::judge_scale_sigma).
TEST(NoFalseTracking, TwinPullingTheScaleIsNotTracking) {
  const pt::Scenario s = twin_scene("lamella", 20, -230, -300, 300, 530);
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella with a twin coming down at 45 deg, dose 20");
  EXPECT_LE(n.false_n, 1) << "TRACKING while the twin pulls the scale (9 before)";
  EXPECT_GE(n.tracked, s.frames / 2) << "tracked before the twin came and after it left";
}

// A twin crossing the lamella on post's path at 90° (pose_envelope_probe
// twin_crosses_over_at_90deg): before the loss the twin's body in the window dragged the last
// TRACKING poses up 1-5 px a frame at χ² ~3.7 (the target's level ~2.1), so the velocity the
// search after the loss kept was the dragged one, (0.24, -1.30) px a frame where the target ran
// (1, 0); the search took the twin on the merged image and the poses following it up at 3 px a
// frame kept that velocity within the step test's 6 px: TRACKING on the twin up to 181 px off
// (50 / 31 poses at 6 / 2.5 e-/px, 3347a57). Now the line is drawn through poses the pattern
// explains only, and once a pose broke the run the probation closes only on five poses in a row
// within 3 px of the kept velocity's line (ContinuityAnchor::keeps_velocity_after_break). The
// needle tip crossed the same way kept a line bent by the drag and stayed UNCERTAIN to the end
// once the twin had left (35 % TRACKING at 20 and 6 e-/px, 3347a57). The poses dragged before the
// loss were left after that: the lamella on its post 12-15 px off and the needle tip 4.6-5.4 px
// off at 6 e-/px (2 and 3 poses, 1479eab), each after UNCERTAIN frames, at χ² significantly above
// the target's level but with a score too near the target's for the material test; now such a
// pose is TRACKING only within 3 px of the line (Tracker::Impl::keep_continuity).
TEST(NoFalseTracking, TwinCrossingAt90DegreesIsNotFollowedAfterTheSearch) {
  struct Row {
    const char* target;
    double dose;
    int before_after_search;
    double min_tracked_share;
    int dragged_before;  // the poses dragged under the twin before the loss, 1479eab
  };
  for (const Row& r : {Row{"lamella_post", 6.0, 47, 0.25, 2}, Row{"lamella_post", 2.5, 30, 0.25, 0},
                       Row{"needle_tip", 20.0, 0, 0.6, 0}, Row{"needle_tip", 6.0, 0, 0.6, 3}}) {
    const pt::Scenario s = twin_scene(r.target, r.dose, 270, 0, -300, 310);
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    char what[96];
    std::snprintf(what, sizeof what, "%s with a twin crossing at 90 deg, dose %.1f", r.target, r.dose);
    const FalseCount n = run_and_count(h, what);
    int false_after_search = 0;
    bool searched_again = false;
    for (std::size_t f = 1; f < h.poses().size(); ++f) {
      const auto& e = h.poses()[f];
      const auto& t = h.records()[f].truth;
      // The search frame itself is left to the search's own checks (at 2.5 e-/px it took the
      // merged image 9.7 px off): counted in false_n below, not here.
      const bool after = searched_again;
      searched_again = searched_again || e.searched;
      if (!after || e.searched || e.state != TrackState::kTracking) continue;
      false_after_search += !(std::hypot(e.x_px - t.x_px, e.y_px - t.y_px) <= 3.0 && pt::declared_angle_error_deg(e, t.phi_deg) <= 10.0);
    }
    std::printf("  %s: false after the re-acquiring search %d\n", what, false_after_search);
    EXPECT_EQ(false_after_search, 0) << what << ": TRACKING on the twin after the search (" << r.before_after_search << " before)";
    EXPECT_EQ(n.false_n, 0) << what << ": TRACKING while dragged by the twin (" << r.dragged_before << " before)";
    EXPECT_GE(n.tracked, r.min_tracked_share * s.frames) << what << ": tracked before the twin came and after it left";
  }
}

// An identical still copy of the target elsewhere in the field at the first start search (a
// twin; the background a target was cut from): it scores as well as the moving target, better
// by the target's scan shear, and the search settled on it, TRACKING for the whole run (found
// probing: 69 of 80 poses on a still twin 320 px away). No score tells a twin from the real
// look-alikes the search check resolves (README Known limitations); the target's place does:
// told a start area (targets[i].start_area), the searches keep to it until the target is
// TRACKING, and every TRACKING pose is on the target. Without the area the run is printed only.
TEST(NoFalseTracking, AStillTwinAtTheStartIsNotTakenWhenTheStartAreaIsTold) {
  for (const double dose : {6.0, 2.5}) {
    const pt::Scenario s = twin_scene("needle_tip", dose, 120, 0, 0, 520);
    for (const bool told : {false, true}) {
      pt::SimHarness h(s, default_tracker());
      ASSERT_TRUE(h.status().ok) << h.status().message;
      if (told) h.tracker()->set_start_area(s.start_x_px, s.start_y_px, 60);
      char what[96];
      std::snprintf(what, sizeof what, "needle_tip with a still twin, dose %.1f, start area %s",
                    dose, told ? "told" : "not told");
      const FalseCount n = run_and_count(h, what);
      if (!told) continue;
      EXPECT_EQ(n.false_n, 0) << what << ": TRACKING on the twin";
      EXPECT_GE(n.tracked, s.frames * 3 / 4) << what;
    }
  }
}

// A twin crossing the needle tip's path from above at 1 e-/px (pose_envelope_probe
// twin_crosses_down_at_45deg): the target, partly covered, was lost, and the search found the twin
// while the line's place held the target itself below the twin's score but at a level the search
// would take as found: the line was forgotten and the poses followed the twin, TRACKING up to 64 px
// off (5 of 180 on 52c8e65, 1 at 20 e-/px). Such a place makes the winner a rival
// (Tracker::rival_on_line): UNCERTAIN, the line kept.
TEST(NoFalseTracking, TwinCoveringTheTargetIsNotTakenByTheSearchAfter) {
  const double dose = 1.0;
  const pt::Scenario s = twin_scene("needle_tip", dose, -230, -300, 300, 530);
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "needle_tip with a twin crossing from above, dose 1");
  EXPECT_EQ(n.false_n, 0) << "TRACKING on the twin after the search (5 before)";
  EXPECT_GE(n.tracked, s.frames / 2) << "tracked before the twin and after it";
}

// The same twin from above and one passing over along the needle tip's axis, at 2.5 and 6 e-/px
// (pose_envelope_probe twin_crosses_down_at_45deg, twin_passes_over): the twin's shaft over the
// target's window lost it, and the search took the twin's clean tip 20-50 px off, TRACKING,
// while the line's place held the target's own local maximum at 0.46-0.54 (the winner 0.68-0.78,
// noise reaching 0.30-0.34 anywhere in the field): below the winner and below "found", so not a
// rival, and the line was forgotten (3c79094: 50.0 / 42.2 px at 2.5 / 6 e-/px from above, 24.2 /
// 20.2 px passing over). A hypothesis on the line above the field's noise floor is the target's
// (Tracker::rival_on_line). Then the merged image dragged the poses 3-5 px along the needle's
// axis, TRACKING on 11-12 frames a row at 2.5 e-/px (3c6591f), its fit within the noise but its
// scale reading 4-10 % up: the continuity check closes only on poses of the trail's size
// (ContinuityAnchor::confirm). The worst left: 3.5 px, the last of the drag.
TEST(NoFalseTracking, TwinFoundWhileTheTargetStillScoresOnTheLineIsNotTracked) {
  struct Row {
    double dose, dy, vx, vy, x0, before_px;
  };
  for (const Row& r : {Row{2.5, -230, -300, 300, 530, 50.0}, Row{6.0, -230, -300, 300, 530, 42.2},
                       Row{2.5, 0, -300, 0, 760, 24.2}, Row{6.0, 0, -300, 0, 760, 20.2}}) {
    const pt::Scenario s = twin_scene("needle_tip", r.dose, r.dy, r.vx, r.vy, r.x0);
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    char what[96];
    std::snprintf(what, sizeof what, "needle_tip with a twin %s, dose %.1f", r.dy == 0 ? "passing over" : "crossing from above",
                  r.dose);
    const FalseCount n = run_and_count(h, what);
    EXPECT_LE(n.false_n, 2) << what << ": TRACKING > 3 px off on the merged image (11-12 a row at 2.5 e-/px before)";
    double worst_px = 0;
    for (std::size_t f = 0; f < h.poses().size(); ++f) {
      const auto& e = h.poses()[f];
      const auto& t = h.records()[f].truth;
      if (e.state == TrackState::kTracking) worst_px = std::max(worst_px, std::hypot(e.x_px - t.x_px, e.y_px - t.y_px));
    }
    std::printf("  %s: worst TRACKING pose %.2f px off\n", what, worst_px);
    EXPECT_LT(worst_px, 8.0) << what << ": TRACKING on the twin the search took (" << r.before_px << " px before)";
  }
}

// A twin crossing the lamella on post's path at 45° twice as fast (pose_envelope_probe
// twin_crosses_over_at_45deg_fast, 2.5 e-/px): the target, covered, was lost; two searches found
// nothing and forgot the line, the third took the twin 94 px off and the poses followed it at
// 8.5 px a frame where the line had run right at 1 px a frame: TRACKING on the twin, 15 poses up to
// 260 px off (bc871a1). A search that forgets the line keeps its velocity: the poses after it are
// vouched for only while they move with it (ContinuityAnchor::forget_keeping_velocity), as a real
// jump's do (pose_accuracy_bench --quick jump rows). The search frame itself is left to the
// search's own checks: its pose on the twin, 94 px off, is the one false pose left.
TEST(NoFalseTracking, TwinTakenByTheSearchAfterALossIsNotTracked) {
  const double dose = 2.5;
  const pt::Scenario s = twin_scene("lamella_post", dose, 270, -600, -600, 535);
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post with a twin crossing over at 45 deg fast, dose " + std::to_string(dose));
  EXPECT_LE(n.false_n, 1) << "TRACKING on the twin the search took (15 before; its search frame 1)";
  EXPECT_GE(n.tracked, s.frames * 3 / 4) << "tracked before the twin and after the target was re-found";
}

// A tool meeting the sample (pose_envelope_probe other_object_*): another object, of another
// pattern, drawn over the target's rim. The needle tip moved against the lamella on post (20 e-/px)
// or the lamella coming to rest over the still needle (2.5 e-/px): the needle held at its place,
// then lost, and the search took a needle-like edge of the lamella 74-88 px away, scoring within
// the needle's level at 2.5 e-/px (0.686 against 0.725) and like a pose 3 px off at 20 (0.80
// against 0.91). The poses followed the edge, TRACKING up to 140 / 105 px off (12 / 55 poses,
// 6287210). A search after a hold that lands beyond the pattern's radius from the held place is
// UNCERTAIN until the poses' fit is at the needle's level (Tracker::Impl::judge_away_from_held).
TEST(NoFalseTracking, AnotherObjectsEdgeTakenAfterAHoldIsNotTracked) {
  struct Meeting {
    double dose;
    bool target_moves;
  };
  for (const Meeting c : {Meeting{20, true}, Meeting{2.5, false}}) {
    pt::Scenario s = envelope_scene("needle_tip", "static", c.dose, 120);
    pt::meet_other_object(s, 60, c.target_moves);
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, std::string("needle_tip and the lamella on post 60 px apart, ") +
                                              (c.target_moves ? "the needle moved" : "the lamella moved") + ", dose " +
                                              std::to_string(c.dose));
    EXPECT_EQ(n.false_n, 0) << "TRACKING on the lamella's edge the search took (12 / 55 before)";
    EXPECT_GE(n.tracked, 48) << "tracked before the lamella covered it";
  }
}

// The same crossing at 2.5 e-/px: under the passing twin the held true pose scored below its own
// turned look-alike (0.53 against 0.61), and a flip check opened there by the jump took the
// look-alike: 84 TRACKING poses 15 px and 180° off. A jump opens no flip check while the pose is
// held, nor unless the last TRACKING poses' line puts the opposite hypothesis, not the pose kept,
// on the target (tracker.cpp, open_flip_on_jump). The 3 left are fc3265b's too (13.9 px, the
// twin's merged image; README, Known limitations). Passes on fc3265b; fails with the check opened
// on every surprising pose (84).
TEST(NoFalseTracking, TwinCrossingOverDoesNotOpenAFlipOntoTheTurnedLookAlike) {
  const double dose = 2.5;
  const pt::Scenario s = twin_scene("lamella_post", dose, 270, -300, -300, 580);
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post with a twin crossing over at 45 deg, dose " + std::to_string(dose));
  EXPECT_LE(n.false_n, 3) << "TRACKING on the turned look-alike after the twin (84 with the flip opened while held)";
}

// A frozen frame buffer (a scan generator's DMA block not refilled, a recording storing a frame
// twice): frames 40-49 deliver frame 39's pixels again while the target moves on. Tracked as new,
// the old image at the moved ROI reads as the target's move, the ROI follows it and the pose runs
// off: pose_envelope_probe frozen_frames_40_49 on 7e87312, 2-10 false TRACKING poses a row, up to
// 190 px off (needle tip 8 at 6 e-/px, 48 px). A frame repeating the last one at every sample is
// held as a bad frame (LOST, reason 16: stale_frame_check.hpp); the next scan is tracked again.
TEST(NoFalseTracking, FrozenFrameBufferIsNotTracked) {
  for (const char* target : {"needle_tip", "lamella_post"}) {
    pt::Scenario s = envelope_scene(target, "smooth", 6, 80);
    auto held = std::make_shared<std::vector<sempose::hal::Pixel>>();
    s.frame_fault = [held](std::uint64_t seq, const sempose::hal::Roi& r, sempose::hal::Pixel* p, sempose::hal::Pixel) {
      const std::size_t n = static_cast<std::size_t>(r.w) * r.h;
      if (seq >= 40 && seq <= 49 && held->size() == n) std::copy(held->begin(), held->end(), p);
      else held->assign(p, p + n);
    };
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, std::string(target) + " frozen frames 40-49, dose 6");
    int stale_held = 0, tracked_after = 0;
    for (std::size_t f = 40; f <= 49; ++f)
      stale_held += h.poses()[f].state != TrackState::kTracking && (h.poses()[f].reason_bits & sempose::pose::kReasonBadFrame);
    for (std::size_t f = 55; f < h.poses().size(); ++f) tracked_after += h.poses()[f].state == TrackState::kTracking;
    EXPECT_EQ(n.false_n, 0) << "TRACKING on a frozen frame (8 / 6 before)";
    EXPECT_EQ(stale_held, 10) << "each repeated frame held as a bad frame";
    EXPECT_GE(tracked_after, 23) << "the scans after the frozen ones are tracked again";
  }
}

// `target` on its smooth path at `dose` with the lower half of every frame 40-49 shifted dx px
// right and dy px down (a scan glitch); counts the ROI frames TRACKING and those of them false
// (> 3 px or > 10° off).
namespace {
struct GlitchCount {
  int frames = 0, tracked = 0, false_n = 0;
};
GlitchCount run_half_frame_glitch(const char* target, double dose, int dx, int dy, bool count_search_frames = false) {
  pt::Scenario s = envelope_scene(target, "smooth", dose, 60);
  s.frame_fault = [dx, dy](std::uint64_t seq, const sempose::hal::Roi& r, sempose::hal::Pixel* p, sempose::hal::Pixel) {
    if (seq < 40 || seq > 49) return;
    // Bottom-up and right-to-left, so each pixel is read before it is overwritten.
    for (int y = r.h - 1; y >= r.h / 2 + dy; --y) {
      sempose::hal::Pixel* row = p + static_cast<std::ptrdiff_t>(y) * r.w;
      const sempose::hal::Pixel* from = p + static_cast<std::ptrdiff_t>(y - dy) * r.w;
      for (int x = r.w - 1; x >= dx; --x) row[x] = from[x - dx];
    }
  };
  pt::SimHarness h(s, default_tracker());
  EXPECT_TRUE(h.status().ok) << h.status().message;
  GlitchCount c;
  c.frames = s.frames;
  if (!h.status().ok) return c;
  h.run();
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const auto& e = h.poses()[f];
    const auto& t = h.records()[f].truth;
    if (e.state != TrackState::kTracking || (e.searched && !count_search_frames)) continue;
    ++c.tracked;
    c.false_n += !(std::hypot(e.x_px - t.x_px, e.y_px - t.y_px) <= 3.0 && pt::declared_angle_error_deg(e, t.phi_deg) <= 10.0);
  }
  std::printf("%s, half the frame shifted (%d, %d) px on frames 40-49, dose %g: %s TRACKING %d, false %d\n", target, dx, dy,
              dose, count_search_frames ? "frames" : "ROI frames", c.tracked, c.false_n);
  return c;
}
}  // namespace

// A scan glitch (pose_envelope_probe half_shifted_12px_frames_40_49): on frames 40-49 the lower
// half of every scanned frame is shifted 12 px to the right, on a target moving ~0.7 px a frame.
// The pose sat between the halves or with the lower one, TRACKING 8-9 px off at a score the
// level rules accept (the needle tip at 20 e-/px: 8 ROI frames). The split check ran only on a
// target standing still; it now runs on a moving one with the shear its motion explains as an
// allowance, so the torn ROI frames are UNCERTAIN. The search frame the glitch's first frame
// leads to is counted in the test after this one.
TEST(NoFalseTracking, ScanGlitchShiftingHalfTheFrameIsNotTracking) {
  const GlitchCount c = run_half_frame_glitch("needle_tip", 20, 12, 0);
  EXPECT_EQ(c.false_n, 0) << "a torn ROI frame TRACKING (8 before)";
  EXPECT_GE(c.tracked, c.frames * 3 / 4) << "tracked outside the glitch";
}

// The search frame the glitch leads to (the torn ROI frame 40 is LOST, frame 41 a field scan torn
// too, the target wholly in its shifted half): the search took it there, 5-20 px off, TRACKING
// (pose_envelope_probe half_shifted_{5,12,20}px: 11 rows at >= 2.5 e-/px). No cut of the window
// straddles the tear and nothing in that frame tells it from a jump; the frame that lost the
// target does (torn, or a jump its score does not vouch for: a 20 px shift puts the second part
// beyond the cuts' reach). So the search after such a loss is UNCERTAIN until an ROI frame
// confirms it: no pose is TRACKING off the target, the search frame counted too.
TEST(NoFalseTracking, SearchAfterALossToATornFrameWaitsForAnRoiFrame) {
  for (const int dx : {12, 20}) {
    const GlitchCount c = run_half_frame_glitch("needle_tip", 20, dx, 0, true);
    EXPECT_EQ(c.false_n, 0) << dx << " px: the search frame after the torn loss TRACKING on the shifted half (1 before)";
    EXPECT_GE(c.tracked, c.frames * 3 / 4) << dx << " px: tracked outside the glitch";
  }
}

// The glitch 20 px over on the lamella on its post at 2.5 e-/px: the search after the torn loss
// found the target's shifted part turned 91° and 13 px off, UNCERTAIN, but the ROI frames after it
// were torn the same way and followed it, TRACKING (4 poses, keeping the target's own velocity):
// an ROI frame alone cannot confirm a search while the glitch lasts. The target had scored
// 0.73 ± 0.013 before the loss, those poses 0.64-0.67, so a pose followed after a loss on a tear
// is TRACKING only once it scores at the level kept before the loss (Tracker::Impl::tear_level).
TEST(NoFalseTracking, PoseAfterALossOnATearScoresAtTheTargetsLevelBeforeTracking) {
  const GlitchCount c = run_half_frame_glitch("lamella_post", 2.5, 20, 0, true);
  EXPECT_EQ(c.false_n, 0) << "the ROI frames after the search on the torn field TRACKING the shifted part";
  EXPECT_GE(c.tracked, c.frames / 2) << "tracked outside the glitch";
}

// The same glitch at 6 e-/px: the tracked scale follows the torn frames' readings (0.99 → 0.97
// over frames 42-46); the scale's share of the split check's allowance excused frame 46, whose
// reading then closed the steady-scale gate on 47-49: 3 ROI frames 9-10 px off TRACKING, their
// parts 1.7-1.9 px apart along the lines at 5-5.6 SD. A change of size does not pull the parts
// apart along the scan lines, so that component is judged without the scale's allowance
// (tracker.cpp, torn()): frame 46 is caught and the gate stays open after it.
TEST(NoFalseTracking, ScanGlitchAlongTheLinesIsNotTrackingWhileTheScaleFollowsIt) {
  const GlitchCount c = run_half_frame_glitch("needle_tip", 6, 12, 0);
  EXPECT_EQ(c.false_n, 0) << "a torn ROI frame TRACKING while the scale followed the tear (3 before)";
  EXPECT_GE(c.tracked, c.frames * 3 / 4) << "tracked outside the glitch";
}

// A tear along y (pose_envelope_probe half_shifted_y_8px_frames_40_49): the lower half of frames
// 40-49 shifted 8 px down. Through the target's middle that reads as the target 6 % taller, and
// the scale followed it: the first torn frame was caught by the split check (parts 2 px apart at
// 6.3 SD), but the tracked scale still took its reading (1.00 → 1.02), the next frame's step
// closed the steady-scale gate, and at 1.06 the stretched pattern fitted both halves: the lamella
// on its post TRACKING 3.7-3.9 px off on 7 frames at 20 e-/px, 6 at 6 e-/px. A frame found torn
// now holds the tracked scale (tracker.cpp, the scale's update) until the parts lie together
// again, so the gate stays open and every torn frame after it is judged at the untorn size.
TEST(NoFalseTracking, ScanGlitchAcrossTheLinesIsNotTakenForAChangeOfSize) {
  for (const double dose : {20.0, 6.0}) {
    const GlitchCount c = run_half_frame_glitch("lamella_post", dose, 0, 8);
    EXPECT_EQ(c.false_n, 0) << "dose " << dose << ": a torn ROI frame TRACKING at the scale the tear read (7 / 6 before)";
    EXPECT_GE(c.tracked, c.frames * 3 / 4) << "dose " << dose << ": tracked outside the glitch";
  }
}

// A dark occluder (pose_envelope_probe dark_occluder_x_gt_400): the field right of x = 400 is a
// flat 4 % level while the lamella on its post moves into it at 150 px/s, at 20 e-/px. Half under
// it the target is lost; a re-acquisition search then took the pose turned ~100° and 10 px off at
// 0.725 (the target's own level 0.94; 0.7 × that admits it), χ² 39.7 where the target's tracked
// frames read ~3, and the frames after it held that pose, TRACKING (9 false poses in the first
// 130 frames, 40 in 200; the best level the explained check excuses with was learnt afresh on
// them after the loss). A pose whose χ² lies significantly above the target's own level learnt
// on frames it tracked well is UNCERTAIN (tracker.cpp, judge_fit).
TEST(NoFalseTracking, PoseTheFitDoesNotExplainAtTheTargetsLevelIsNotTracking) {
  pt::Scenario s = envelope_scene("lamella_post", "static", 20, 130);
  s.start_x_px = 250;
  s.start_y_px = 240;
  move_linearly(s, 150, 0, 60);
  s.frame_fault = [](std::uint64_t, const sempose::hal::Roi& r, sempose::hal::Pixel* p, sempose::hal::Pixel m) {
    for (int y = 0; y < r.h; ++y)
      for (int x = std::max(0, 400 - r.x); x < r.w; ++x) p[static_cast<std::ptrdiff_t>(y) * r.w + x] = static_cast<sempose::hal::Pixel>(0.04 * m);
  };
  pt::SimHarness h(s, default_tracker());
  ASSERT_TRUE(h.status().ok) << h.status().message;
  const FalseCount n = run_and_count(h, "lamella_post moving under a dark occluder, dose 20");
  EXPECT_EQ(n.false_n, 0) << "TRACKING while > 3 px or > 10 deg off (9 before)";
  EXPECT_GE(n.tracked, 45) << "tracked before the occluder covers it";
}

namespace {
// A pose_envelope_probe scene (started at 30°, smooth motion, 60 frames) whose detector lags
// the frames by τ 4 px (1000 ns at 250 ns), and what its TRACKING poses' x along the line and
// the tracker's τ status say.
struct LagRun {
  FalseCount n;
  double mean_dx = 0;
  sempose::pose::Tracker::DetectorTauStatus tau;
  std::string setup_warning;  // Tracker::create's status message
};
pt::Scenario lagged_scene(const char* target, double dose) {
  pt::Scenario s;
  s.target = target;
  s.dose_e = dose;
  s.frames = 60;
  s.start_phi_deg = 30;
  return s;
}
LagRun run_lagged(const pt::Scenario& s, const std::string& label) {
  pt::SimHarness h(s, default_tracker());
  LagRun r;
  EXPECT_TRUE(h.status().ok) << h.status().message;
  if (!h.status().ok) return r;
  r.n = run_and_count(h, label);
  double sum = 0;
  for (std::size_t f = 0; f < h.poses().size(); ++f)
    if (h.poses()[f].state == TrackState::kTracking) sum += h.poses()[f].x_px - h.records()[f].truth.x_px;
  r.mean_dx = r.n.tracked ? sum / r.n.tracked : 0.0;
  r.tau = h.tracker()->detector_tau_status();
  r.setup_warning = h.status().message;
  std::printf("  mean x error %+.2f px, frames' tau read %.2f px (rho %.3f, lag-2 excess %+.3f%s), frames disagree with the told "
              "tau %d, pattern sets overruled %d\n",
              r.mean_dx, r.tau.tau_px, r.tau.rho, r.tau.lag2_excess, r.tau.inconsistent ? ", inconsistent" : "",
              static_cast<int>(r.tau.frames_disagree), r.tau.patterns_told_overruled);
  return r;
}
}  // namespace

// pose_envelope_probe's detector_tau_4px: τ told right (1000 ns, 4 px), the pattern set given
// the frames' dwell_ns (250) but recorded through no low-pass. The told lags cancel while the
// frames lag the pattern by 3.5 px: main's poses sat +2.3…+2.9 px along the line, 103 TRACKING
// > 3 px off over the case's rows (18 on the lamella on its post at 6 e-/px, 5 on the needle tip
// at 2.5). The pattern's own noise reads it lag-free (ρ ~0.01 against the 0.78 its dwell_ns
// implies): that reading's lag is used (a setup warning, Tracker::detector_tau_status()).
TEST(NoFalseTracking, PatternToldAtTheFramesDwellButRecordedLagFreeIsCorrected) {
  for (const auto& [target, dose] : {std::pair{"lamella_post", 6.0}, std::pair{"needle_tip", 2.5}}) {
    pt::Scenario s = lagged_scene(target, dose);
    s.edit_run = [](sempose::config::SimConfig& c) { c.detector_tau_ns = 1000; };  // the frames only
    char label[96];
    std::snprintf(label, sizeof label, "%s, pattern lag-free told at 250 ns, tau 4 px, dose %g", target, dose);
    const LagRun r = run_lagged(s, label);
    EXPECT_EQ(r.n.false_n, 0) << target << ": TRACKING > 3 px off (main: 18 / 5)";
    EXPECT_LT(std::fabs(r.mean_dx), 1.5) << target << ": mean x error (main: +2.9 / +2.6 px)";
    EXPECT_EQ(r.tau.patterns_told_overruled, 1) << target;
    EXPECT_NE(r.setup_warning.find("pattern set 0: its own noise shows"), std::string::npos) << r.setup_warning;
    EXPECT_FALSE(r.tau.frames_disagree) << target << ": the frames' τ was told right";
  }
}

// pose_envelope_probe's detector_tau_4px_told_1px: a detector swapped (or its bandwidth switched)
// since its calibration — the frames through τ 4 px, the tracker told 1 px (250 ns), a lag-free
// pattern (dwell_ns 0). The frames' readings (ρ 0.77 against the told 0.37) disagree: reported
// (Tracker::detector_tau_status(), the run's summary; fc3265b said nothing) and, as they read as a
// low-pass (the lag-2 check), their lag used: with the told lag kept the poses sat +2.2…+2.3 px
// along the line, 2 TRACKING 3.2 px off at 2.5 e-/px (afe0cba). Dropped lines disagree too but
// are no low-pass: the told lag stays for them (below).
TEST(NoFalseTracking, DetectorSwappedSinceItsCalibrationIsReportedAndMeasured) {
  for (const double dose : {6.0, 2.5}) {
    pt::Scenario s = lagged_scene("lamella_post", dose);
    s.detector_tau_ns = 1000;
    s.told_detector_tau_ns = 250;
    s.pattern_lag_free = true;
    const LagRun r = run_lagged(s, "lamella_post, tau 4 px told 1 px");
    EXPECT_TRUE(r.tau.frames_disagree) << "the frames' lag contradicts the told τ";
    EXPECT_TRUE(r.tau.frames_lag_measured) << "a low-pass's readings: their lag is used";
    EXPECT_EQ(r.tau.patterns_told_overruled, 0) << "the lag-free pattern was told lag-free";
    EXPECT_EQ(r.n.false_n, 0) << dose << " e-/px: TRACKING > 3 px off (afe0cba: 0 / 2)";
    EXPECT_LT(std::fabs(r.mean_dx), 1.2) << dose << " e-/px: mean x error (afe0cba: +2.29 / +2.31 px)";
  }
}

// pose_envelope_probe's every_4th_line_dropped_tau_told: τ 120 ns told right, every 4th line
// of each frame dropped (4 % of full scale). The dropped lines pass the τ estimate's gate and
// read ρ 0.73–0.79 at 20 e-/px; a check that used the frames' reading in place of the told τ
// took a 2.5–3.1 px lag out of x: 71 TRACKING poses > 3 px off on the lamella on its post (24 /
// 15 on the needle tip / procedural lamella). The told lag stays; the disagreement is reported.
TEST(NoFalseTracking, DroppedLinesDoNotOverruleAToldDetectorTau) {
  struct Case {
    const char* target;
    double dose, tau_ns;
  };
  // τ 120 ns (the probe's), 250 ns (1 px: dropped lines read δ +0.04…+0.10 there, the nearest
  // to a low-pass's) and 500 ns (2 px) at the dwell of 250 ns.
  for (const Case c : {Case{"lamella_post", 20, 120}, Case{"lamella_post", 20, 250}, Case{"needle_tip", 2.5, 250},
                       Case{"lamella", 6, 500}}) {
    pt::Scenario s = lagged_scene(c.target, c.dose);
    s.frames = 80;
    s.detector_tau_ns = c.tau_ns;
    s.frame_fault = [](std::uint64_t, const sempose::hal::Roi& r, sempose::hal::Pixel* p, sempose::hal::Pixel m) {
      for (int y = 0; y < r.h; ++y)
        if ((r.y + y) % 4 == 0)
          std::fill(p + static_cast<std::ptrdiff_t>(y) * r.w, p + static_cast<std::ptrdiff_t>(y + 1) * r.w,
                    static_cast<sempose::hal::Pixel>(0.04 * m));
    };
    char label[112];
    std::snprintf(label, sizeof label, "%s, every 4th line dropped, tau %g ns told, dose %g", c.target, c.tau_ns, c.dose);
    const LagRun r = run_lagged(s, label);
    EXPECT_EQ(r.n.false_n, 0) << label << ": TRACKING > 3 px off (the frames' reading used: 71 at tau 120 ns)";
    EXPECT_LT(std::fabs(r.mean_dx), 0.6) << label << ": mean x error";
    // Where the dropped lines pass the lag-2 check (τ 250 / 500 ns) they read 7–8 px: a lag beyond
    // the corrected range, as a slow detector at a short dwell reads — UNCERTAIN, not corrected.
    if (r.tau.frames_lag_measured) {
      EXPECT_GT(r.tau.beyond_frames, 0) << label << ": a measured lag used and corrected";
    }
  }
}

// pose_envelope_probe's defocus_3px / defocus_5px: the beam's PSF steps from sharp to σ 3 / 5 px
// at 25 % of the run. The blurred frames' poses score at the target's level with χ² at its level,
// but the fit's curvature on them is a fraction of the pattern's (Σ ∂T·∂f / gain against Σ (∂T)²:
// 0.13-0.54 of it where the sharp frames read 0.54-0.85), so the pose's σ, taken from the
// pattern's curvature, was 1.2-3.2x too small (RMS(error/σ) on the blurred frames) and poses 3-4
// px off were TRACKING: 4 on the procedural lamella at 6 e-/px (5 px), 3 at 2.5 e-/px (3 px),
// 1 on the needle tip at 6 e-/px (5 px). σ is widened by the frame's blur against the target's
// own (Tracker::Impl::widen_for_blur) and a blurred pose is not narrowed by a prediction made
// from poses as blurred. The sharp part of the run stays TRACKING.
TEST(NoFalseTracking, DefocusedFramesAreNotTrustedOnThePatternsCurvature) {
  struct Case {
    const char* target;
    double defocus_px, dose;
  };
  for (const Case& c : {Case{"lamella", 5, 6}, Case{"lamella", 3, 2.5}, Case{"needle_tip", 5, 6}}) {
    pt::Scenario s = envelope_scene(c.target, "smooth", c.dose, 80);
    const double psf = c.defocus_px;
    s.edit_run = [psf](sempose::config::SimConfig& sc) {
      sc.defocus_px.from = 0;
      sc.defocus_px.to = psf;
      sc.defocus_px.start_s = 0.25;
    };
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    char label[96];
    std::snprintf(label, sizeof label, "%s, defocus to %g px at 25 %%, dose %g", c.target, c.defocus_px, c.dose);
    const FalseCount n = run_and_count(h, label);
    int sharp_tracked = 0;  // TRACKING among frames 5-17, before the PSF steps in (frame ~20)
    for (std::size_t f = 5; f < 18 && f < h.poses().size(); ++f) sharp_tracked += h.poses()[f].state == TrackState::kTracking;
    std::printf("  TRACKING on the sharp frames 5-17: %d of 13\n", sharp_tracked);
    EXPECT_EQ(n.false_n, 0) << label << ": TRACKING > 3 px or > 10 deg off (4 / 3 / 1 before)";
    EXPECT_GE(sharp_tracked, 10) << label << ": the sharp frames stay TRACKING";
  }
}

// A pattern recorded over one patch of background, the target now over another (the run's scene
// drawn with another seed: the procedural lamella's grains and the background under the
// pattern's corners differ, the lamella's outline is the same). The structure the frames do not
// have pulled the tracked scale and the place together: 1.00 -> 1.05-1.07 while the place ran 3-4.5
// px off, TRACKING on σ 0.3-0.5 px (5 poses over the 4 runs; judge_scale_drift).
TEST(NoFalseTracking, PatternRecordedOverAnotherBackground) {
  for (std::uint64_t seed : {12u, 13u, 14u, 15u}) {
    pt::Scenario s = envelope_scene("lamella", "smooth", 20, 150);
    s.edit_run = [seed](sempose::config::SimConfig& sc) { sc.seed = seed; };
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    const FalseCount n = run_and_count(h, "lamella over another background, seed " + std::to_string(seed) + ", dose 20");
    EXPECT_EQ(n.false_n, 0) << "TRACKING while > 3 px or > 10 deg off";
    // (129-147 of 150: the drifting frames UNCERTAIN; 144-147 before judge_scale_drift.)
    EXPECT_GE(n.tracked, s.frames * 4 / 5) << "the lamella followed TRACKING where its scale holds";
  }
}

namespace {

// The run's TRACKING poses against the target where the beam saw it (a full-field search
// frame's mid-scan is far from that): false = > 3 px or > 10° off; search frames apart.
struct TrackingJudged {
  int tracking = 0, false_poses = 0, false_on_searches = 0;
  double worst_px = 0, worst_deg = 0;
};
TrackingJudged judge_tracking(const pt::SimHarness& h) {
  TrackingJudged j;
  for (std::size_t f = 0; f < h.poses().size(); ++f) {
    const auto& e = h.poses()[f];
    if (e.state != TrackState::kTracking) continue;
    const auto& seen = h.records()[f].as_scanned;
    const double px = std::hypot(e.x_px - seen.x_px, e.y_px - seen.y_px);
    const double deg = pt::declared_angle_error_deg(e, seen.phi_deg);
    const bool off = px > 3.0 || deg > 10.0;
    if (e.searched) {
      j.false_on_searches += off;
      continue;
    }
    ++j.tracking;
    j.worst_px = std::max(j.worst_px, px);
    j.worst_deg = std::max(j.worst_deg, deg);
    j.false_poses += off;
  }
  return j;
}

}  // namespace

// An ROI that leaves the pattern little room: the walk's best place sits on the ROI's edge
// whenever the target moved farther than the margin, and the true maximum lies outside the
// window. Found probing (`tracker.roi_size_px` equal to the pattern's side, accepted): TRACKING
// poses 6.6 px / 7° off. Equal sizes are refused now, and a place on the edge is not a
// confirmed maximum: never TRACKING. The frequent re-searches of a fast target are judged too:
// the field scan shears it (~10 px across the needle tip's rows at 470 px/s), and its search
// pose, 3.5-4 px off, was TRACKING 1-2 times a row; it waits for an ROI frame now
// (Tracker::Impl::sheared_by_motion).
class NoRoomInTheRoi : public ::testing::TestWithParam<std::tuple<std::string, int>> {};

TEST_P(NoRoomInTheRoi, APlaceOnTheRoisEdgeIsNeverTracking) {
  pt::Scenario s;
  s.target = std::get<0>(GetParam());
  s.dose_e = 6.0;
  s.motion = "fast";
  s.frames = 80;
  sempose::config::TrackerConfig tc = default_tracker();
  const int room = std::get<1>(GetParam());
  tc.roi_size_px = tc.pattern_size_px + room;
  pt::SimHarness h(s, tc);
  if (room == 0) {
    EXPECT_FALSE(h.status().ok) << "an ROI the pattern's size was accepted";
    EXPECT_NE(h.status().message.find("as large as tracker.roi_size_px"), std::string::npos) << h.status().message;
    return;
  }
  ASSERT_TRUE(h.status().ok) << h.status().message;
  h.run();
  const TrackingJudged j = judge_tracking(h);
  std::printf("ROI = pattern + %d px, %-12s fast, 6 e-/px: ROI frames TRACKING %d, false %d (worst %.1f px, %.1f deg); "
              "false on search frames %d\n",
              room, s.target.c_str(), j.tracking, j.false_poses, j.worst_px, j.worst_deg, j.false_on_searches);
  EXPECT_EQ(j.false_poses, 0);
  EXPECT_EQ(j.false_on_searches, 0) << "a search pose of the sheared fast target was TRACKING";
  // Not by never tracking: with room for the motion the target is followed (65 / 69 / 57 of 80).
  if (room >= 8) {
    EXPECT_GE(j.tracking, 40) << "the edge rule took a target with room for its motion";
  }
}

INSTANTIATE_TEST_SUITE_P(TargetsRoom, NoRoomInTheRoi,
                         ::testing::Combine(::testing::Values("needle_tip", "lamella_post", "lamella"), ::testing::Values(0, 2, 4, 8)));

// A slow detector nobody told sempose about: the frames through a line low-pass of 6–12 px
// mean delay, the pattern a clean recording. The lag taken out of x is the low-pass's mean
// delay, but the smeared target's correlation peak moves less (hostile round 12: TRACKING poses
// 3–6 px off on σx 0.5 px). Beyond Tracker::kMaxCorrectedLagPx a pose is not vouched for, and
// the status says how far the lag went. The same detector told a τ of 1 px (calibrated before it
// was swapped, or at a longer dwell than the governor now scans at): the frames disagree, and
// afe0cba kept the told lag — 7–59 of 60 poses a case TRACKING 3.5–7.9 px off (checked with the
// frames' lag switched off). Now the frames' lag is used, and beyond the range the pose is
// UNCERTAIN as untold.
class SlowDetector : public ::testing::TestWithParam<std::tuple<std::string, int>> {};

TEST_P(SlowDetector, ALagBeyondTheCorrectedRangeIsNeverTracking) {
  for (const bool told_wrong : {false, true}) {
    pt::Scenario s;
    s.target = std::get<0>(GetParam());
    s.dose_e = 6.0;
    s.motion = "smooth";
    s.frames = 60;
    s.detector_tau_ns = std::get<1>(GetParam()) * static_cast<double>(s.dwell_ns);
    s.pattern_lag_free = true;
    s.tell_detector_tau = told_wrong;
    s.told_detector_tau_ns = told_wrong ? s.dwell_ns : 0;  // 1 px
    pt::SimHarness h(s, default_tracker());
    ASSERT_TRUE(h.status().ok) << h.status().message;
    h.run();
    const TrackingJudged j = judge_tracking(h);
    const auto d = h.tracker()->detector_tau_status();
    std::printf("slow detector tau %d px%s, %-12s 6 e-/px: TRACKING %d / %d, false %d (worst %.1f px); measured tau %.1f px, "
                "beyond on %.0f frames (up to %.1f px)\n",
                std::get<1>(GetParam()), told_wrong ? " told 1 px" : "", s.target.c_str(), j.tracking, s.frames,
                j.false_poses + j.false_on_searches, j.worst_px, d.tau_px, d.beyond_frames, d.beyond_max_px);
    EXPECT_EQ(j.false_poses + j.false_on_searches, 0) << (told_wrong ? "told 1 px" : "untold");
    EXPECT_GT(d.beyond_frames, 0) << "the lag's range was never said to be passed" << (told_wrong ? " (told 1 px)" : "");
    if (told_wrong) {
      EXPECT_TRUE(d.frames_disagree) << "the frames' lag contradicts the told τ";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(TargetsLags, SlowDetector,
                         ::testing::Combine(::testing::Values("needle_tip", "lamella_post", "lamella"), ::testing::Values(6, 8, 12)));
