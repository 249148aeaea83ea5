// The detector's finite bandwidth along a scanned line (issue 13 item 7): a first-order
// low-pass of time constant τ sampled once per pixel dwell d, y_i = y_(i-1) + a·(x_i - y_(i-1)),
// a = 1 - exp(-d/τ), delays the image by its group delay at zero frequency, (1 - a)/a =
// exp(-d/τ)/(1 - exp(-d/τ)) px along the line (τ 120 ns: 0.77 px at 100 ns, 0.14 px at 250 ns).
// A pose matched against a pattern recorded at another dwell is shifted by the difference of
// the two lags; the tracker takes it out of x (scan lines run along +x).
#pragma once

#include <cmath>
#include <cstdint>

namespace sempose::pose {

struct DetectorLag {
  // The lag in px at pixel dwell dwell_ns; 0 when τ or the dwell is not known (≤ 0).
  static double px(double tau_ns, double dwell_ns) noexcept {
    if (!(tau_ns > 0) || !(dwell_ns > 0)) return 0.0;
    const double r = std::exp(-dwell_ns / tau_ns);
    return r / (1.0 - r);
  }
};

}  // namespace sempose::pose
