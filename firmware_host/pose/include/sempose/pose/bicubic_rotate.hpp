// The one resampler of the pose engine: a square image turned about its centre, bicubic
// (Keys, a = −0.5), samples outside clamped to the border. Setup only (the bank's rotated
// copies, the turned shape masks).
#pragma once

namespace sempose::pose {

// Rotates src (size×size, row-major) by phi_deg about its centre, counter-clockwise on the
// screen (README: Conventions) into out (size×size).
void rotate_pattern(const float* src, int size, double phi_deg, float* out) noexcept;

}  // namespace sempose::pose
