// The full-field start search (at start and after a loss): the frame box-downsampled by
// search_downsample and correlated at every coarse angle (one FFT each); the strongest
// separated local maxima become candidates; each candidate's ROI is loaded at full resolution
// and refined by an angle sweep around the coarse angle (its peak looked for only near the
// coarse position), and by its own position search at the opposite angle (φ+180°, a
// look-alike of elongated targets). The best candidate by coarse + fine score wins.
// Setup allocates; search() is RT.
#pragma once

#include <cstdint>
#include <vector>

#include "sempose/config/tracker_config.hpp"
#include "sempose/pose/angle_sweep.hpp"
#include "sempose/pose/candidate_list.hpp"
#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/roi_loader.hpp"

namespace sempose::pose {

// The last tracked angle, if any: a start search's tie-break between a target and its 180°
// look-alike (a target does not turn by 180° while it is lost).
struct AnglePrior {
  bool known = false;
  double phi_deg = 0;
};

class StartSearch {
 public:
  StartSearch(const config::TrackerConfig& cfg, const EngineSizes& sizes, const AngleGrid& angles,
              FftCorrelator& coarse, FftCorrelator& half, RoiLoader& loader, const OrientationWalk& walk,
              AngleSweep& sweep, CorrelationMaps& maps);

  // RT: searches a w×h frame (row stride w). The result is in the ROI at (roi_x, roi_y) of
  // the frame, which the loader holds afterwards only if it was the last candidate.
  Measurement search(const PatternBank& bank, const std::uint16_t* pixels, int w, int h, int bits,
                     const AnglePrior& prior, int& roi_x, int& roi_y) noexcept;

  // Exact scores of a target and its 180° look-alike within kFlipTieScore of each other are a
  // tie at a few electrons per pixel (measured on the simulated lamellae: wrong-way-round
  // leads of 0.003–0.016 at doses 1–6 e⁻/px; the true flip of lamella_post at 2.5 e⁻/px
  // leads by 0.03). A tie goes to the angle within kFlipPriorDeg of the last tracked one (a
  // last pose from a torn frame can be far off: no prior then), else stays with the coarse
  // level's choice.
  static constexpr float kFlipTieScore = 0.02f;
  static constexpr double kFlipPriorDeg = 45.0;
  bool prefer_opposite(const Measurement& coarse_choice, const Measurement& opposite,
                       const AnglePrior& prior) const noexcept;

  std::size_t memory_bytes() const noexcept;

 private:
  const config::TrackerConfig& cfg_;
  const EngineSizes& sizes_;
  const AngleGrid& angles_;
  FftCorrelator& coarse_;
  FftCorrelator& half_;
  RoiLoader& loader_;
  const OrientationWalk& walk_;
  AngleSweep& sweep_;
  CorrelationMaps& maps_;
  std::vector<std::int32_t> coarse_frame_;  // the frame, box-downsampled
  std::vector<float> coarse_map_;
  CandidateList candidates_;
};

}  // namespace sempose::pose
