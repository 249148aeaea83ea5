// A bounded search in angle within one loaded ROI: FFT correlations of the binned ROI at
// centre ± window every step (always including the centre), the best map's peak kept, then
// the orientation walk from the best angle. The tracker's recovery when the walk hits its
// bound or the score collapses, and the start search's refinement of a coarse candidate.
// RT, no allocation (the maps are the tracker's).
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include "sempose/pose/angle_grid.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/measurement.hpp"
#include "sempose/pose/orientation_walk.hpp"
#include "sempose/pose/peak_finder.hpp"

namespace sempose::pose {

// Two binned-ROI ZNCC maps: the one being written and the best so far (swapped, not copied).
class CorrelationMaps {
 public:
  explicit CorrelationMaps(std::size_t len) : a_(len, 0.0f), b_(len, 0.0f) {}
  CorrelationMaps(const CorrelationMaps&) = delete;
  CorrelationMaps& operator=(const CorrelationMaps&) = delete;
  float* work() noexcept { return work_; }
  const float* best() const noexcept { return best_; }
  void keep_work_as_best() noexcept { std::swap(work_, best_); }
  std::size_t memory_bytes() const noexcept { return (a_.size() + b_.size()) * sizeof(float); }

 private:
  std::vector<float> a_, b_;
  float* work_ = a_.data();
  float* best_ = b_.data();
};

class AngleSweep {
 public:
  AngleSweep(FftCorrelator& half, const OrientationWalk& walk, const AngleGrid& angles, CorrelationMaps& maps) noexcept
      : half_(half), walk_(walk), angles_(angles), maps_(maps) {}

  Measurement sweep(const PatternBank& bank, int j_centre, double window_deg, double step_deg, int max_moves,
                    const SearchWindow& window = {}) noexcept;

 private:
  FftCorrelator& half_;
  const OrientationWalk& walk_;
  const AngleGrid& angles_;
  CorrelationMaps& maps_;
};

}  // namespace sempose::pose
