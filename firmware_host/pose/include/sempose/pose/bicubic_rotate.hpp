// The pose engine's resamplers (setup only): rotate_pattern, a square image turned about its
// centre, bicubic (Keys, a = −0.5), samples outside clamped to the border (the turned shape
// masks); and PatternRotator, the bank's rotated copies (pattern and its noise model).
#pragma once

#include <vector>

namespace sempose::pose {

// Rotates src (size×size, row-major) by phi_deg about its centre, counter-clockwise on the
// screen (README: Conventions) into out (size×size). Keys's smoothing depends on the sample
// phase: none at 0/90/180/270° (exact pixel permutations), most at half-pixel phases.
void rotate_pattern(const float* src, int size, double phi_deg, float* out) noexcept;

// Setup: the same map as rotate_pattern, with a smoothing that does not depend on the angle.
// The image is extended past its border (clamped, then tapered to its mean so the canvas is
// periodic), band-limited interpolated (periodic sinc, exact at the image's own samples) to a
// kUp× finer grid once, and each rotation samples that grid with Keys: at kUp = 4 Keys's
// phase-dependent loss is < 1 % even at the Nyquist frequency of the image (≈ 22 % on the
// image's own grid), so every angle — 0° included — is the band-limited rotation.
class PatternRotator {
 public:
  static constexpr int kUp = 4;
  PatternRotator(const float* src, int size);  // allocates (size + 2·margin)² · kUp² floats
  void rotate(double phi_deg, float* out) const noexcept;

 private:
  int n_ = 0, margin_ = 0, len_ = 0, up_len_ = 0;
  std::vector<float> up_;  // up_len_² samples; grid point u is canvas position u / kUp
};

}  // namespace sempose::pose
