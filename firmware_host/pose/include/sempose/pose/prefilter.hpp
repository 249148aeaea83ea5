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
  static constexpr int kRingRows = 8;  // horizontally filtered rows in flight (5 read, 3 ahead)
  int passes_, max_w_, max_h_;
  std::vector<std::int32_t> a_, b_, row_;  // a_: a pass's output before the last; b_: the ring
};

// The factor apply() scales a constant image by (256 per pass, less the shifts that keep
// the output within 20 bits): filtered units per raw unit for input of `bits` bits.
double prefilter_dc_gain(int passes, int bits) noexcept;

// The share of a raw pixel's noise variance the prefilter keeps (in raw units²; × the DC gain²
// for filtered units). White noise keeps Σk² of the 2-D kernel; noise correlated along the line
// with lag-d correlation ρ^d (the detector's first-order low-pass) keeps Σ_y k² · Σ_ij k_i k_j
// ρ^|i−j| — at ρ = 0.37 (τ = 1 px) 1.7× as much for one pass: the binomial kernel cannot
// average away what neighbouring pixels share.
class PrefilterNoiseGain {
 public:
  PrefilterNoiseGain() : PrefilterNoiseGain(0) {}
  explicit PrefilterNoiseGain(int passes);  // setup: the kernel's autocorrelation
  double white() const noexcept { return lag_[0] * lag_[0]; }
  // Σ_i k_i k_(i+d) of the 1-D kernel (all passes); 0 beyond its length.
  double lag(std::size_t d) const noexcept { return d < lag_.size() ? lag_[d] : 0.0; }
  // RT: the gain for noise whose lag-1 correlation along x is rho (and 0 across lines).
  double line_correlated(double rho) const noexcept {
    double along = lag_[0], rho_d = 1.0;
    for (std::size_t d = 1; d < lag_.size(); ++d) {
      rho_d *= rho;
      along += 2.0 * lag_[d] * rho_d;
    }
    return lag_[0] * along;
  }

 private:
  std::vector<double> lag_;  // Σ_i k_i k_(i+d) of the 1-D kernel (all passes), d = 0 … its length − 1
};

// Setup: the same filter on a float pattern (n×n, edges replicated), passes times.
void prefilter_pattern(float* pattern, int n, int passes);

}  // namespace sempose::pose
