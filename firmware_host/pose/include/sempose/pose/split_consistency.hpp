// Split-scan consistency of one pose (issue 13 item 6: a torn frame is never TRACKING). The
// model says the target is rigid while its ROI is scanned; a target that jumped mid-scan breaks
// that along the slow scan axis: the lines scanned before the jump show it at one place, the
// lines after it at another. At the pose's integer grid point (the one the exact score is taken
// at, no new search) the pattern's support is cut into the rows scanned first and the rows
// scanned last, at each of kCuts row cuts (between row quarters), and each part is fitted on
// its own by the linearised rigid model f ≈ b + a·t − a·δ·∇t (one Lucas–Kanade step: gain a,
// offset b and the part's displacement δ from the pose, ∇t by central differences of the
// bank's pattern). A whole frame puts both parts at the same place up to noise, whatever
// share of the pattern's structure each part holds; a torn frame's parts pull apart. The
// difference of the two δ is judged by its Mahalanobis distance under the parts' covariances:
// each from its own residual variance per pixel (the detector noise plus whatever the model
// misses there, so never below the noise), inflated by the prefilter's correlation as the
// score noise model is (mask pixels over score_samples). The linear step reads a jump beyond
// the pattern's smoothing scale short (an 8 px tear: 0.8–1.3 px), so δ is a direction and a
// significance, not the tear's size.
// The same pass sums the support's kTiles × kTiles tiles, each fitted the same way, and one
// affine displacement field (shift, turn, change of size, shear: what a rigid target scanned
// while it moves and its tracked scale lags leaves) is fitted to them: parts left off that field
// move differently from the rest (a target moving over a static background its pattern holds;
// a gripper's jaws opening). As for the cuts, the linear step sees a disagreement only within
// a few px.
// RT: one pass over the support (15 sums per pixel), no allocation.
#pragma once

#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {

struct SplitConsistency {
  bool valid = false;
  // Of the cuts, the one whose parts lie farthest apart in noise SDs: that distance (√ of the
  // Mahalanobis d²) and the parts' displacement difference in loaded-ROI pixels.
  double z = 0, apart_px = 0;
  // The two parts' centroid rows' distance (loaded-ROI rows): how much later the second part
  // was scanned, so how far a moving target's own motion puts the parts apart.
  double rows_apart = 0;
  int cut = 0;  // 1 … kCuts: the cut after cut quarters of the support's rows
  // The same along the scan lines (x) alone, at the cut where that component is farthest apart
  // in its SDs: a change of the target's size pulls the parts apart along the slow axis (rows
  // below the centre show it lower), not along the lines; a tear that moves the lines does.
  double line_z = 0, line_apart_px = 0, line_rows_apart = 0;
  // The pattern's tiles (kTiles × kTiles over its support) each fitted on its own the same way,
  // and one affine displacement field fitted to all of them: what is left says parts of the
  // window move differently (a target moving over a static background the pattern holds, the
  // pose between the two). tiles_chi2 over tiles_dof (2 per tile fitted − 6), and the largest
  // tile's own distance from the fitted field (loaded-ROI px) among the tiles that lie
  // significantly off it (their own χ², 2 dof, above 9.21: 1 %).
  bool tiles_valid = false;
  double tiles_chi2 = 0, tiles_apart_px = 0;
  int tiles_dof = 0;
};

class SplitConsistencyCheck {
 public:
  static constexpr int kParts = 4;  // row quarters; cuts between them
  static constexpr int kCuts = kParts - 1;
  static constexpr int kTiles = 3;  // tiles per side of the support (kTiles² parts)
  // noise_inflation: the score noise model's pixels per independent noise sample (mask pixels
  // over score_samples; set at setup once they are known).
  SplitConsistencyCheck(const ExactScorer& scorer, double noise_inflation) noexcept
      : scorer_(scorer), inflation_(noise_inflation) {}
  void set_noise_inflation(double v) noexcept { inflation_ = v; }
  // RT: the pattern at angle j of the bank with its top-left at (ux, uy) of the scorer's loaded
  // ROI (rows in scan order). Not valid when the window leaves the ROI or a part does not fit.
  SplitConsistency measure(const PatternBank& bank, int j, int ux, int uy) const noexcept;

 private:
  const ExactScorer& scorer_;
  double inflation_;
};

}  // namespace sempose::pose
