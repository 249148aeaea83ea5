// The score attainable in a window: the ZNCC a perfectly aligned, noise-free pattern of the
// target would reach there given the frame's noise, √(S'/(S'+N')) with S' the signal variance
// and N' the noise variance after the prefilter. A true match explains the window's signal;
// textured background that merely resembles the pattern explains little of it, so the loss
// policy compares a match's score with this (README: States, attainable score).
// The noise comes from the raw window with its correlation along the scan line
// (line_correlated_noise: the detector's low-pass), through the prefilter's gain on that
// coloured noise; a white-noise model (Immerkær × Σk²) reads 0.5–0.8× the noise on a
// low-passed frame and keeps too little of it through the prefilter, so it promised the
// procedural lamella under charging + defocus at 2.5 e⁻/px 0.92 where it reaches 0.53–0.6,
// and every right pose was refused. S' is taken as the raw signal variance (var − noise): the prefilter's loss of
// fine signal detail is not modelled (README: Known limitations).
#pragma once

#include <cstdint>

#include "sempose/pose/pattern_support.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/window_noise.hpp"

namespace sempose::pose {

struct AttainableScore {
  double score = 0;  // √(S'/(S'+N')), 0 when the window has no signal
  WindowNoise noise;  // the raw window's noise (variance, lag-1 correlation along the line)
  double window_var = 0;  // the raw window's variance (signal + noise)
};

// RT, no allocation, one pass over the p×p window (plus the noise pass): px is a w×h raw frame
// (row stride w), (cx, cy) the pose of the pattern centre in it; the window is clamped into
// the frame. A frame smaller than the pattern scores 0.
AttainableScore attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy, int p,
                                 const PrefilterNoiseGain& gain) noexcept;

// The same over a shape mask's pixels only: `bands` (n_bands of them, in the p×p window's
// coordinates: PatternBank::support_bands at the match's angle) hold the pixels a masked
// pattern is scored on; the signal is their variance, the noise still the whole window's. A
// masked pattern explains only its support, so the whole window's signal (moving parts,
// background) would promise it a score it cannot reach.
AttainableScore attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy, int p,
                                 const MaskBand* bands, int n_bands, const PrefilterNoiseGain& gain) noexcept;

// The recorded pattern's own factor (setup): the score above assumes a noise-free pattern, but
// the ZNCC of two noisy copies of one signal is the product of each copy's √(S/(S+N')). This
// is the pattern's: the same formula on the raw n×n pattern px with its noise (PatternBank
// measures it with line_correlated_noise for σ: pattern_noise_var/rho, not estimated again).
// 1 when no noise was read. Measured: 0.996-0.998 at 20 e-/px, 0.967-0.985 at 2.5 for the
// benchmark's averaged patterns, ~0.65 for a 96² crop of one frame.
double pattern_attainable_factor(const std::uint16_t* px, int n, const WindowNoise& noise,
                                 const PrefilterNoiseGain& gain) noexcept;

}  // namespace sempose::pose
