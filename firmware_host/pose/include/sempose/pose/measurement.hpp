// One frame's measurement of a target as the stages pass it along: the integer grid point
// (angle index, displacement of the pattern's top-left in the loaded ROI), the sub-pixel /
// sub-step offsets of the fit, the exact score there and the position peak's PSR.
#pragma once

#include <cstdint>

namespace sempose::pose {

struct Measurement {
  bool valid = false;
  int j = 0;                      // angle index in the bank
  int ux = 0, uy = 0;             // integer displacement in the loaded ROI
  double dx = 0, dy = 0, dj = 0;  // sub-pixel / sub-step offsets
  float score = 0, psr = 0;
  bool psr_valid = false;
  int steps = 0;                  // correlations and exact scores spent
  bool unsettled = false;         // the walk hit its per-frame bound
  bool on_window_edge = false;    // the walk's place is on the loaded window's edge: a maximum not confirmed
  bool background_plane = false;  // the sub-pixel fit scored with a brightness ramp as nuisance (SubpixelFit)
  // The ZNCC the noise model says the target reaches in the window at this pose (Tracker:
  // attainable score); < 0: not measured yet (the walk's own decisions run without it).
  float attainable = -1.0f;
  // The pose lands where the motion seen so far does not put it and its score does not vouch
  // for it (Tracker: motion check): not the target, however well the pattern fits there.
  bool implausible = false;
  // A start search's result: the best exact score of the other hypothesis 180° away (the
  // opposite angle's own position search), −2: none. How far the chosen one leads it says
  // whether this dose told a near-symmetric target's two ends apart (Tracker: flip check).
  float flip_score = -2.0f;
  // A start search's result: its coarse (×8) score, and the rank (exact + coarse score, what
  // the search chooses by) of the best candidate at another place (more than a quarter
  // pattern away), −4: none. How far the result's rank leads it says whether this dose told
  // the target from its best look-alike (Tracker: search check).
  float coarse_score = 0.0f;
  float runner_up_rank = -4.0f;
  // The refinement seam's outcome (FitStatus: 0 off, 1 refined, 2 diverged — the walk's pose
  // kept —, 3 skipped) and the scale the fit found relative to the loaded ROI's (1: not fitted).
  std::uint8_t refine_status = 0;
  float refined_scale = 1.0f;
};

}  // namespace sempose::pose
