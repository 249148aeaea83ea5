#pragma once
// A pattern's rotational self-similarity (README: Symmetric targets). A lamella, a bead, a cross
// or a square pad looks (nearly) the same turned by 360°/n: no tracker can tell its angle φ from
// φ + 360°/n once it has lost the angle's continuity (a jump, a search), so its angle is known
// modulo 360°/n only. Measured at setup from the bank's own copies: the pattern against itself
// turned by 360°/n (n = 2, 3, 4, 6), over the small shifts a symmetry centre off the pattern's
// centre needs. A turn whose copy matches at least as well as a pose the false-pose rule already
// counts as wrong (kFalsePx / kFalseDeg off, in the direction the pattern tells best:
// nearest_off_pose_score, off_pose_score.hpp) is told from the target no better than such a pose:
// the pattern's declared order is the largest such n whose divisors pass too. Measured (20 and
// 2.5 e-/px recordings): the procedural lamella 0.82 / 0.74 turned 180° against 0.69 / 0.64,
// order 2; the lamella on its post 0.55 / 0.53 against 0.68 / 0.63 (its post breaks it) and
// the needle tip 0.39 against 0.74 / 0.70, order 1. Setup only.
#include <array>

namespace sempose::pose {

class PatternBank;

struct PatternSymmetry {
  static constexpr std::array<int, 4> kOrders = {2, 3, 4, 6};
  // The largest shift (px, each axis) tried for a turned copy: a symmetry centre up to
  // kNearShiftPx / 2 off the pattern's centre (an operator centres a recorded pattern on the
  // target within a few px). Farther shifts match part of the target only (the lamella on its
  // post turned 180° matches its body 15-17 px off): a look-alike the flip check tells apart
  // (tracker.cpp, open_flip_on_jump), not symmetry.
  static constexpr int kNearShiftPx = 4;
  // And at least this, whatever a pose off the target scores: a fine random texture (a particle
  // field, a rough surface) scores ~0 a few px off, and its copy turned 90° at 0.07-0.12 passed as
  // "the same look" (order 4 or 6 declared, the angle then judged modulo 90°: hostile round 13).
  // The lowest real same look measured is the procedural lamella's 0.74 at 2.5 e-/px.
  static constexpr double kMinSameLookScore = 0.5;
  int order = 1;  // the pattern looks the same turned by 360°/order: its angle is known modulo that
  std::array<double, 4> self_score{};  // per kOrders: the best ZNCC turned by 360°/n, shifts ≤ kNearShiftPx
  double same_look_score = 1;          // the score a turn must reach to count (nearest_off_pose_score)
  // The symmetry centre from the pattern's centre (pattern px, x right, y down; order > 1): the
  // point the pattern turns about onto itself.
  double centre_dx_px = 0, centre_dy_px = 0;
};

// same_look_score: the pattern's nearest_off_pose_score.
PatternSymmetry measure_symmetry(const PatternBank& bank, double same_look_score);

}  // namespace sempose::pose
