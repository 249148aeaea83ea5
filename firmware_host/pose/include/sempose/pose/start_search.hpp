// The full-field start search (at start and after a loss): the frame box-downsampled by
// search_downsample, resampled by 1/s for each scale level s (search_scale_levels.hpp, over
// search_scale_min…max times the expected scale, or only the expected scale after a loss or
// when a SELECT gave the microscope's nm/px: ScalePrior), and correlated at every coarse angle (one FFT each, at the
// scanned field's FFT size; the levels below 1, whose frame is enlarged, on a second and larger correlator); the strongest
// separated local maxima over every level become candidates; each candidate's ROI is loaded
// at full resolution, resampled by 1/s, and refined by an angle sweep around the coarse angle
// (its peak looked for only near the coarse position), and by its own position search at the
// opposite angle (φ+180°, a look-alike of elongated targets), then its scale by the scale
// probe's scores over the level's span. The best candidate by coarse + fine score wins; when
// its scale is away from the expected one, the same place is measured at the expected scale
// too and the away one is kept only on clear evidence (ScaleEvidenceCheck); the winner is
// measured once more in its ROI resampled at its refined scale.
// Setup allocates; search() is RT.
#pragma once

#include <cstdint>
#include <vector>

#include "sempose/config/tracker_config.hpp"
#include "sempose/pose/pose_frame.hpp"
#include "sempose/pose/angle_sweep.hpp"
#include "sempose/pose/candidate_list.hpp"
#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/roi_loader.hpp"
#include "sempose/pose/roi_rescaler.hpp"
#include "sempose/pose/scale_evidence.hpp"
#include "sempose/pose/scale_probe.hpp"
#include "sempose/pose/search_scale_levels.hpp"

namespace sempose::pose {

// The last tracked angle, if any: a start search's tie-break between a target and its 180°
// look-alike (a target does not turn by 180° while it is lost).
struct AnglePrior {
  bool known = false;
  double phi_deg = 0;
};

// The scale the search expects: a prior, not a free parameter. Tracking starts at it unless a
// match at another scale is clearly better (ScaleEvidenceCheck).
struct ScalePrior {
  // A SELECT's nm/px over the pattern's, else 1; after a loss the last tracked scale.
  double scale = 1.0;
  // One level at `scale`, refined within ±kNarrowSpan: after a loss (the target was just
  // tracked at that scale) or when a SELECT gave the microscope's nm/px. Otherwise the levels
  // of tracker.search_scale_min…max times `scale`.
  bool narrow = false;
};

class StartSearch {
 public:
  StartSearch(const config::TrackerConfig& cfg, const EngineSizes& sizes, const AngleGrid& angles,
              FftCorrelator& coarse, FftCorrelator* coarse_wide, FftCorrelator& half, RoiLoader& loader, RoiRescaler& rescaler,
              const ScaleProbe& probe, const ScaleEvidenceCheck& evidence, const OrientationWalk& walk, AngleSweep& sweep,
              CorrelationMaps& maps);

  // RT: searches a w×h frame (row stride w). The result is in the scanned (not resampled)
  // coordinates of the ROI at (roi_x, roi_y) of the frame; found_scale is the target's size
  // over the pattern's there. The loader holds some candidate's ROI afterwards. A candidate
  // within a quarter pattern of a place in `held` (this frame's coordinates: other targets'
  // objects) is not taken, nor counted as a look-alike.
  Measurement search(const PatternBank& bank, const std::uint16_t* pixels, int w, int h, int bits,
                     const AnglePrior& prior, const ScalePrior& scale_prior, int& roi_x, int& roi_y,
                     double& found_scale, const HeldPlaces& held = {}) noexcept;

  // The scale levels searched when the scale is unknown (search_scale_levels.hpp; first 1).
  const std::vector<double>& scale_levels() const noexcept { return levels_; }

  // Exact scores of a target and its 180° look-alike within kFlipTieScore of each other are a
  // tie at a few electrons per pixel (measured on the simulated lamellae: wrong-way-round
  // leads of 0.003–0.016 at doses 1–6 e⁻/px; the true flip of lamella_post at 2.5 e⁻/px
  // leads by 0.03). A tie goes to the angle within kFlipPriorDeg of the last tracked one (a
  // last pose from a torn frame can be far off: no prior then), else stays with the coarse
  // level's choice.
  static constexpr float kFlipTieScore = 0.02f;
  static constexpr double kFlipPriorDeg = 45.0;
  // Over scale levels a candidate's score loses this per level (25 %) its scale is away from
  // the expected one: the real lamella scene holds a look-alike 190 px away that matched at
  // 1.25 and 95° better than the target at 1 at 2.5 e⁻/px (pose_accuracy_bench warped spin).
  static constexpr double kScaleTiePerLevel = 0.05;
  static constexpr double kCoarseTiePerLevel = 0.06;
  // A found scale that would change how the ROI is loaded (RoiRescaler::kMinChange away from
  // the expected one) must be clear (ScaleEvidenceCheck), or the match at the expected scale
  // is kept. At 0.05 the gripper's first search at 2.5 e⁻/px took 1.051 unchecked and its
  // first tracked pose was dragged 3.6 px (pose_accuracy_bench --only gripper jaws).
  static constexpr double kPriorBand = RoiRescaler::kMinChange;
  // A narrow search's refinement span: one level's reach (√kSearchLevelRatio, ±11.8 %) plus a
  // probe step, the scale a magnification ramp can move while the target is lost.
  static constexpr double kNarrowSpan = 0.148;
  bool prefer_opposite(const Measurement& coarse_choice, const Measurement& opposite,
                       const AnglePrior& prior) const noexcept;

  std::size_t memory_bytes() const noexcept;

 private:
  // One candidate's fine measurement at scale level s: loaded (resampled by 1/s when s ≠ 1),
  // swept, the opposite angle tried; its scale refined (factor over s).
  struct Fine {
    Measurement m;
    int rx = 0, ry = 0, rw = 0, rh = 0;
    double load_scale = 1.0, factor = 1.0;
    double scanned_score = -2.0;  // the scale probe's score on the scanned ROI, if loaded as scanned
  };
  struct Tried {
    Fine fine;
    double cx = 0, cy = 0;  // the coarse place's pattern centre in the frame
    int k = 0, level = 0;
    float coarse_score = 0, rank = 0;
  };
  // The fine measurement of the place whose pattern centre is at (cx, cy) of the frame, coarse
  // angle k, at scale level_scale: ROI loaded resampled, sweep, opposite angle, scale refined;
  // common_score: also the candidates' common score on the scanned ROI (a search over levels).
  Fine measure_place(const PatternBank& bank, const std::uint16_t* px, int w, int h, int bits, const AnglePrior& prior,
                     double cx, double cy, int k, double level_scale, double span, bool common_score) noexcept;
  // f's measurement with its position in the scanned ROI's coordinates.
  Measurement in_scanned_roi(const Fine& f) const noexcept;
  static void set_top_left(Measurement& m, double x, double y) noexcept;
  // Loads the w×h-frame ROI at (rx, ry) resampled by 1/s (raw when s is within
  // RoiRescaler::kMinChange of 1); returns the scale it was loaded at, 0 when flat.
  double load_at(const std::uint16_t* px, int w, int rx, int ry, int rw, int rh, int bits, double s) noexcept;
  // The scale factor of the loaded ROI's target at m: the probe's score over ± span, the best
  // of them and a parabola through its neighbours.
  double refine_factor(const PatternBank& bank, const Measurement& m, double span) const noexcept;
  // Bilinear: level(x', y') = coarse(s·x', s·y'), up to max_w × max_h (the correlator's size).
  void resample_coarse(int cw, int ch, double s, int max_w, int max_h, int& lw, int& lh) noexcept;

  const config::TrackerConfig& cfg_;
  const EngineSizes& sizes_;
  const AngleGrid& angles_;
  FftCorrelator& coarse_;       // the scanned field's size
  FftCorrelator* coarse_wide_;  // the levels below 1's enlarged frame, when larger (else null)
  FftCorrelator& half_;
  RoiLoader& loader_;
  RoiRescaler& rescaler_;
  const ScaleProbe& probe_;
  const ScaleEvidenceCheck& evidence_;
  const OrientationWalk& walk_;
  AngleSweep& sweep_;
  CorrelationMaps& maps_;
  std::vector<double> levels_;
  std::vector<double> active_;              // the levels of this search (no allocation: capacity kept)
  std::vector<std::int32_t> coarse_frame_;  // the frame, box-downsampled
  std::vector<std::int32_t> level_frame_;   // ... and resampled by 1/s
  std::vector<float> coarse_map_;
  std::vector<Tried> tried_;  // one per candidate
  CandidateList candidates_;
};

}  // namespace sempose::pose
