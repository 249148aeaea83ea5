// Whether a recorded frame shows the pattern's window as the frames before it did. The
// paper's pattern is the mean of N frames of a standing target; averaging frames in which the
// target moves or turns smears it into something no frame shows (a needle moving 7 px a
// frame, averaged over 10 frames, gave poses 39 px off reported as TRACKING). `sempose
// pattern` averages only the leading frames that pass this check.
#pragma once

#include <cstddef>
#include <vector>

#include "sempose/hal/image.hpp"

namespace sempose::cli {

struct StillnessCheck {
  bool still = true;
  double zncc = 0;      // ZNCC of the new scan's window with the mean of the frames so far
  double expected = 0;  // what it reaches on a standing window, given both sides' noise
  double lowest = 0;    // the lowest ZNCC still called standing (expected less noise and estimator bias)
};

// The mean so far of the size × size window at (x0, y0) over `frames` scans (row-major,
// size² values) and one scan's noise variance in it (`scan_noise_var`, the first frame's),
// against the same window of `frame` (whole pixels, inside the image). Still when their ZNCC
// is what the noise leaves of a standing window: √(S/(S + N/frames)) · √(S/(S + N)), S the
// new scan's variance less its noise. Motion and turns lower it; since the mean's noise
// shrinks as frames are added, a slow drift shows before its smear is larger than the noise.
StillnessCheck check_stillness(const std::vector<double>& mean_window, std::size_t frames, double scan_noise_var,
                               const hal::Image& frame, int x0, int y0, int size);

// One scan's noise variance in the window (the detector's, correlation along the line included).
double scan_noise_var(const hal::Image& frame, int x0, int y0, int size);

// The noise estimate (Immerkær's, read along the line) reads up to ~10 % too little noise on
// the skewed shot noise of a few electrons per pixel, which raises `expected` by up to this
// share of (1 − expected).
inline constexpr double kNoiseBiasShare = 0.1;
// Standard errors of the ZNCC allowed below `expected` (≈ (1 − r²)/√(n/2) for n pixels, the
// half for the detector's correlation along the line).
inline constexpr double kStandardErrors = 4.0;

}  // namespace sempose::cli
