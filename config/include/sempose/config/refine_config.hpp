// Settings of the final Gauss–Newton fit at the refinement seam (the `tracker.refine:` mapping;
// firmware_host/pose gauss_newton_fit / pose_refinement). After the orientation walk's
// quadratic fit, the fit moves the pose (x, y, φ and optionally scale, with gain and offset)
// to the least-squares match of the bank's pattern at the walk's angle on the prefiltered ROI.
#pragma once

#include <cstdint>
#include <string>

namespace sempose::config {

class Section;

struct RefineConfig {
  bool enabled = false;
  // Gauss–Newton passes over the pattern's pixels per frame (the worst case: this many).
  std::int32_t max_iterations = 3;
  // A fit that moves the pose farther than this from the walk's (rim displacement for angle
  // and scale, in px) left the walk's basin: the walk's pose is kept and marked.
  double max_move_px = 1.5;
  // What is fitted: "prefiltered" — the exact scorer's prefiltered ROI against the bank's
  // prefiltered pattern over its support (the walk's own objective); "raw" — the ROI as scanned
  // against the recorded pattern over the same support (no prefilter: the least-squares
  // estimator for white noise, but the recorded background under the rim pulls it harder).
  std::string source = "prefiltered";
  // Fit the scale too (otherwise the ROI's tracked scale is taken as exact).
  bool fit_scale = true;
  // Report the fit's position (false: only its angle, the walk's position kept — the fit
  // still moves position jointly to find the angle). Measured: the fit lowers the angle's
  // noise part but not the position's (README: Known limitations).
  bool fit_position = true;
  // Only measurements scoring at least this are refined (below it the fit has too little signal
  // to beat the walk and a look-alike is as likely).
  double min_score = 0.2;
};

// Reads a `refine:` mapping (tracker.refine); config/src/refine_section.cpp.
void read_refine(Section& section, RefineConfig& out);

}  // namespace sempose::config
