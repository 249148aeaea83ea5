#pragma once
// The best score a pose kFalsePx / kFalseDeg off the target can reach, as a share of the score
// the target itself reaches: the pattern's own ZNCC against itself shifted by the false-pose
// radius (along x, y and both diagonals, the largest) or turned by the false-pose angle
// (LossPolicy::kFalsePx / kFalseDeg). A window the pattern fits worse than that, counted from
// the score the target reaches there at its own fit level (tracker.cpp, judge_fit), holds no pose
// within the radius a TRACKING pose must keep. Setup only.
#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {

double off_pose_score(const PatternBank& bank, double angle_step_deg) noexcept;
// The smallest of the same offsets' scores: the false pose the pattern tells best from the
// target. A hypothesis scoring above it is no more told from the target than a pose the
// false-pose rule already counts as wrong (pattern_symmetry.hpp).
double nearest_off_pose_score(const PatternBank& bank, double angle_step_deg) noexcept;

}  // namespace sempose::pose
