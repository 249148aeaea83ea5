// ScanSpeedGovernor in virtual time (governor_model.hpp): convergence, step response,
// bounds, quality lengthening and the minimum pose rate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "governor_model.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace sempose::pipeline {
namespace {

hal::ScanLimits limits() {
  hal::ScanLimits l;
  l.min_dwell_ns = 100;
  l.max_dwell_ns = 10'000;
  l.dwell_step_ns = 50;
  l.line_flyback_ns = 2'000;
  return l;
}

// The dwell that makes a w×h scan last compute × (1 + margin), rounded up to the step.
std::uint32_t ideal_dwell(const hal::ScanLimits& l, const config::GovernorConfig& c,
                          std::int64_t compute_ns, int w, int h) {
  const double d = (compute_ns * (1 + c.margin) - h * double(l.line_flyback_ns)) / (double(w) * h);
  auto q = static_cast<std::uint32_t>(std::ceil(d / l.dwell_step_ns)) * l.dwell_step_ns;
  return std::clamp(q, l.min_dwell_ns, l.max_dwell_ns);
}

TEST(Governor, ConvergesToExpectedDwellAtFixedComputeCost) {
  config::GovernorConfig c;
  const auto l = limits();
  for (std::int64_t compute : {800'000LL, 3'000'000LL, 9'000'000LL}) {
    for (std::uint32_t initial : {100u, 5'000u}) {
      c.initial_dwell_ns = initial;
      ScanSpeedGovernor gov(c, l, 1);
      auto steps = test::run_model(gov, l, {}, 60, [&](int) { return compute; });
      const auto want = ideal_dwell(l, c, compute, 128, 128);
      for (int k = 20; k < 60; ++k) {
        EXPECT_EQ(steps[k].dwell_ns, want) << "compute " << compute << " initial " << initial << " frame " << k;
        EXPECT_FALSE(steps[k].overrun || steps[k].dropped) << "frame " << k;
      }
    }
  }
}

// Step in compute cost (e.g. more orientation steps): settles within 20 frames, no overrun
// after that and no oscillation (the dwell is constant once settled).
void check_step(std::int64_t before_ns, std::int64_t after_ns) {
  config::GovernorConfig c;
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 1);
  constexpr int kStep = 50;
  auto steps = test::run_model(gov, l, {}, 120, [&](int k) { return k < kStep ? before_ns : after_ns; });
  const auto want = ideal_dwell(l, c, after_ns, 128, 128);
  for (int k = kStep + 20; k < 120; ++k) {
    EXPECT_FALSE(steps[k].overrun || steps[k].dropped) << before_ns << "->" << after_ns << " frame " << k;
    EXPECT_EQ(steps[k].dwell_ns, want) << before_ns << "->" << after_ns << " frame " << k;
  }
  // No oscillation during settling either: the dwell moves monotonically toward the target.
  int direction_changes = 0;
  int last_sign = 0;
  for (int k = kStep; k < 120; ++k) {
    const long diff = long(steps[k].dwell_ns) - long(steps[k - 1].dwell_ns);
    const int sign = diff > 0 ? 1 : diff < 0 ? -1 : 0;
    if (sign != 0 && last_sign != 0 && sign != last_sign) ++direction_changes;
    if (sign != 0) last_sign = sign;
  }
  EXPECT_EQ(direction_changes, 0) << before_ns << "->" << after_ns;
}

TEST(Governor, StepUpInComputeCostSettlesWithin20Frames) { check_step(1'500'000, 4'000'000); }
TEST(Governor, StepDownInComputeCostSettlesWithin20Frames) { check_step(4'000'000, 1'500'000); }

TEST(Governor, NoisyComputeCostDoesNotOscillate) {
  config::GovernorConfig c;
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 1);
  // ±5 % deterministic jitter around 2 ms, one 3x outlier every 50 frames.
  auto steps = test::run_model(gov, l, {}, 400, [](int k) {
    const double jitter = 0.05 * std::sin(k * 1.7);
    return static_cast<std::int64_t>(2'000'000 * (1 + jitter) * (k % 50 == 25 ? 3 : 1));
  });
  int changes = 0;
  int overruns = 0;
  for (int k = 40; k < 400; ++k) {
    changes += steps[k].dwell_ns != steps[k - 1].dwell_ns;
    const bool late = steps[k].overrun || steps[k].dropped;
    overruns += late;
    if (k % 50 < 25 || k % 50 > 28) {
      EXPECT_FALSE(late) << "frame " << k << " is not near an outlier";
    }
  }
  EXPECT_LE(changes, 8) << "the hysteresis band must absorb ±5 % jitter and single outliers";
  EXPECT_LE(overruns, 3 * 8) << "only the frames right after an outlier may be late";
}

TEST(Governor, BoundsAreRespected) {
  config::GovernorConfig c;
  c.min_dwell_ns = 220;   // rounded up to the 50 ns step: 250
  c.max_dwell_ns = 2'030; // rounded down: 2000
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 1);
  EXPECT_EQ(gov.min_dwell_ns(), 250u);
  EXPECT_EQ(gov.max_dwell_ns(), 2000u);
  auto steps = test::run_model(gov, l, {}, 400, [](int k) {
    return k < 100 ? std::int64_t{10'000} : std::int64_t{60'000'000};  // far below / far above
  });
  for (const auto& s : steps) {
    EXPECT_GE(s.dwell_ns, 250u);
    EXPECT_LE(s.dwell_ns, 2000u);
    EXPECT_EQ(s.dwell_ns % 50, 0u);
  }
  EXPECT_EQ(steps[99].dwell_ns, 250u);
  EXPECT_EQ(steps[399].dwell_ns, 2000u);
}

TEST(Governor, LowMatchQualityLengthensDwellDownToMinPoseRate) {
  config::GovernorConfig c;
  c.min_pose_rate_hz = 50;  // 20 ms per pose at most
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 1);
  auto steps = test::run_model(gov, l, {}, 200, [](int) { return std::int64_t{2'000'000}; },
                               [](int k) { return k < 60 || k >= 140 ? 0.9f : 0.2f; });
  const auto base = ideal_dwell(l, c, 2'000'000, 128, 128);
  EXPECT_EQ(steps[59].dwell_ns, base);
  const auto longest = std::max_element(steps.begin(), steps.end(),
                                        [](auto& a, auto& b) { return a.dwell_ns < b.dwell_ns; });
  EXPECT_GT(longest->dwell_ns, base * 2) << "poor matches must buy a cleaner image";
  for (const auto& s : steps) {
    EXPECT_LE(l.scan_time_ns(128, 128, s.dwell_ns), 20'000'000 + 128 * 50 * 128)
        << "never below the minimum pose rate (one dwell step of slack)";
  }
  EXPECT_EQ(steps[199].dwell_ns, base) << "recovers once the matches are good again";
}

// A ROI pose the tracker reported LOST buys the next ROIs more dwell, though its score is above
// low_score (the tracker judges scores against its own levels); good poses give it back.
TEST(Governor, ALostRoiPoseLengthensTheNextRoiDwell) {
  config::GovernorConfig c;
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 1);
  for (int k = 0; k < 40; ++k) {
    gov.observe(0, 2'000'000, 0.9f, 9.0f, true);
    (void)gov.next_dwell_ns(0, 128, 128);
  }
  const std::uint32_t settled = gov.next_dwell_ns(0, 128, 128);
  EXPECT_EQ(settled, ideal_dwell(l, c, 2'000'000, 128, 128));
  std::uint32_t after_losses = settled;
  for (int k = 0; k < 3; ++k) {
    gov.observe(0, 2'000'000, 0.6f, 9.0f, false);  // LOST: not tracking, score above low_score
    gov.lost_on_roi(0);
    after_losses = gov.next_dwell_ns(0, 128, 128);
  }
  EXPECT_GE(after_losses, static_cast<std::uint32_t>(settled * 1.9)) << "three LOST ROI poses: 1.25^3 ≈ 1.95× the dwell";
  for (int k = 0; k < 200; ++k) {
    gov.observe(0, 2'000'000, 0.9f, 9.0f, true);
    (void)gov.next_dwell_ns(0, 128, 128);
  }
  EXPECT_EQ(gov.next_dwell_ns(0, 128, 128), settled) << "recovers once the poses are good again";
}

// A target's detector floor (its tracker's shortest correctable dwell, a slow detector's) holds
// its ROI dwell at or above it, only that target's, within the minimum pose rate's cap; 0 lifts it.
TEST(Governor, ADetectorFloorHoldsTheDwellWithinThePoseRateCap) {
  config::GovernorConfig c;
  c.min_pose_rate_hz = 50;  // 20 ms a pose: the cap on a 128² ROI lies at ~1170 ns
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 2);
  auto settle = [&](std::uint8_t t) {
    std::uint32_t d = 0;
    for (int k = 0; k < 200; ++k) {
      gov.observe(t, 800'000, 0.9f, 9.0f, true);
      d = gov.next_dwell_ns(t, 128, 128);
    }
    return d;
  };
  const std::uint32_t free_dwell = settle(0);
  ASSERT_LT(free_dwell, 200u) << "the compute alone must want a short dwell for the case to mean anything";
  gov.set_dwell_floor(0, 430);
  EXPECT_EQ(settle(0), 450u) << "the floor, on the generator's 50 ns step";
  EXPECT_EQ(settle(1), free_dwell) << "another target's floor";
  gov.set_dwell_floor(0, 5'000);
  const std::uint32_t capped = settle(0);
  EXPECT_LT(capped, 5'000u);
  EXPECT_LE(l.scan_time_ns(128, 128, capped), 20'000'000 + 128 * 50 * 128) << "the pose rate's cap holds over the floor";
  gov.set_dwell_floor(0, 0);
  EXPECT_EQ(settle(0), free_dwell) << "no floor: back to the compute's dwell";
}

TEST(Governor, TwoTargetsShareTheRateBudget) {
  config::GovernorConfig c;
  c.min_pose_rate_hz = 50;
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 2);
  auto steps = test::run_model(gov, l, {128, 128, 2}, 200, [](int) { return std::int64_t{2'000'000}; },
                               [](int) { return 0.1f; });
  for (const auto& s : steps) EXPECT_LE(l.scan_time_ns(128, 128, s.dwell_ns), 10'000'000 + 128 * 50 * 128);
}

TEST(Governor, DisabledKeepsInitialDwell) {
  config::GovernorConfig c;
  c.enabled = false;
  c.initial_dwell_ns = 400;
  const auto l = limits();
  ScanSpeedGovernor gov(c, l, 1);
  auto steps = test::run_model(gov, l, {}, 30, [](int) { return std::int64_t{5'000'000}; });
  for (const auto& s : steps) EXPECT_EQ(s.dwell_ns, 400u);
}

TEST(Governor, ObserveAndNextDwellDoNotAllocate) {
  config::GovernorConfig c;
  ScanSpeedGovernor gov(c, limits(), 2);
  rt::alloc::ScopedArm arm;
  const auto before = rt::alloc::this_thread_allocations();
  for (int k = 0; k < 1000; ++k) {
    gov.observe(static_cast<std::uint8_t>(k % 2), 1'000'000 + k, 0.8f, 9.0f, true);
    (void)gov.next_dwell_ns(static_cast<std::uint8_t>(k % 2), 128, 128);
  }
  EXPECT_EQ(rt::alloc::this_thread_allocations(), before);
}

}  // namespace
}  // namespace sempose::pipeline
