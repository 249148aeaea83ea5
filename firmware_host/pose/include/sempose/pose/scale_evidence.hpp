// Whether a start search's match at a scale away from the expected one (a SELECT's nm/px over
// the pattern's, else 1; after a loss the last tracked scale) is clear enough to replace the
// match at the expected scale. Both matches are scored on the same pixels of the loaded ROI
// (every pixel inside both stretched supports), and so are the two placed patterns against
// each other (ρ). Two things must hold:
//  - the gain r_away − r_expected exceeds kSigmas × its noise at this dose. On white noise
//    the gain's noise is √(2(1 − ρ) q / N): q, the noise's share of the window's variance, is
//    taken as 1 − r_away² (all the misfit counted as noise: an upper bound), N the pixel count;
//  - it is what a rigid target at that scale would show: a copy of the away-placed pattern
//    scores ρ · r_away against the expected-placed one, so a rigid target loses r_away (1 − ρ)
//    at the expected scale; at least kRigidShare of that loss must be seen. A deforming target
//    (a gripper whose jaws opened) fits a larger rigid pattern a little better, but loses far
//    less than a rigid larger target at the expected scale, because its body still fits there.
// RT, no allocation.
#pragma once

#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/measurement.hpp"
#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {

struct ScaleEvidence {
  bool valid = false;     // false: the window left the ROI, or too few pixels
  double r_away = 0;      // ZNCC of the match away from the expected scale
  double r_expected = 0;  // ZNCC of the match at the expected scale, same pixels
  double rho = 0;         // ZNCC of the two placed patterns against each other, same pixels
  double noise = 0;       // the gain's standard deviation from noise (above)
  double pixels = 0;
  bool clear = false;     // both conditions hold
};

class ScaleEvidenceCheck {
 public:
  // The gain must be this many of its noise standard deviations: the pixels are prefiltered
  // (correlated noise, fewer independent samples than N) and several candidates are tried.
  static constexpr double kSigmas = 4.0;
  // Share of the rigid target's loss at the expected scale that must be seen. Measured on the
  // first start searches of pose_accuracy_bench --quick: rigid targets at 0.8 and 1.25 (needle
  // tip, lamella on post, procedural lamella; 6 and 2.5 e⁻/px) showed 0.57–0.95 of it, the
  // gripper with its jaws opening (found at 1.09–1.28 or 0.87–0.94) 0.06–0.40.
  static constexpr double kRigidShare = 0.5;

  explicit ScaleEvidenceCheck(const ExactScorer& scorer) noexcept : scorer_(scorer) {}

  // away / expected: the two matches' poses in the loaded ROI (pattern top-left + sub-pixel,
  // angle index), each with the pattern stretched by its factor (its scale over the ROI's).
  ScaleEvidence compare(const PatternBank& bank, const Measurement& away, double away_factor, const Measurement& expected,
                        double expected_factor) const noexcept;

 private:
  const ExactScorer& scorer_;
};

}  // namespace sempose::pose
