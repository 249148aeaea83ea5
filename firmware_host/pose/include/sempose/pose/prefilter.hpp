// Low-pass prefilter for noisy SEM frames: separable 5-tap binomial [1 4 6 4 1] passes
// (σ ≈ 1 px each) in integers, edges replicated. At single-digit electrons per pixel most
// of a pixel's variance is shot noise; correlating smoothed frame and smoothed pattern is
// the matched filter for the texture's band and lifts the ZNCC peak well above the noise.
// Integer output keeps the correlator's window sums exact; each pass scales by 256 and is
// shifted back to at most 20 bits.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sempose::pose {

class Prefilter {
 public:
  // max_w/max_h: the largest region filtered (setup allocates the scratch rows).
  Prefilter(int passes, int max_w, int max_h);
  int passes() const noexcept { return passes_; }
  // RT: filters a w×h region (row stride in px) into out (w×h, row stride w).
  void apply(const std::uint16_t* src, int w, int h, std::ptrdiff_t stride, int bits, std::int32_t* out) noexcept;

 private:
  int passes_, max_w_, max_h_;
  std::vector<std::int32_t> a_, b_, row_;
};

// The factor apply() scales a constant image by (256 per pass, less the shifts that keep
// the output within 20 bits): filtered units per raw unit for input of `bits` bits.
double prefilter_dc_gain(int passes, int bits) noexcept;

// Setup: the same filter on a float pattern (n×n, edges replicated), passes times.
void prefilter_pattern(float* pattern, int n, int passes);

}  // namespace sempose::pose
