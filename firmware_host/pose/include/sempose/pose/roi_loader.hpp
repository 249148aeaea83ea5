// Loads one ROI into the two levels the tracker scores it at: prefiltered at full resolution
// for the exact scorer, and 2×2-binned into the half-resolution FFT correlator (one forward
// FFT) where the whole ROI is correlated to find the peak. Setup allocates; load() is RT.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/prefilter.hpp"

namespace sempose::pose {

class RoiLoader {
 public:
  // max_roi_px: the largest ROI side (larger ROIs are cut to it).
  RoiLoader(int prefilter_passes, int max_roi_px, ExactScorer& scorer, FftCorrelator& half);

  // RT: false when the binned ROI is flat (nothing to correlate).
  bool load(const std::uint16_t* pixels, int w, int h, std::ptrdiff_t stride, int bits) noexcept;

  std::size_t memory_bytes() const noexcept;

 private:
  int max_roi_px_;
  Prefilter prefilter_;
  ExactScorer& scorer_;
  FftCorrelator& half_;
  std::vector<std::int32_t> filtered_;  // prefiltered ROI
  std::vector<std::int32_t> binned_;    // its 2×2 means
};

}  // namespace sempose::pose
