// A smooth analytic texture rendered exactly at a known pose (no interpolation), so a pose
// stage's answer on it is known. Shared by the unit tests of the walk, the start search and σ.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace sempose::test {

// The target's texture in its own frame (u right, v down, origin at its centre): two blobs of
// different width and a slanted ripple, so position and angle are both well defined.
// wide_blob / narrow_blob are the blobs' widths (px², larger = smoother target).
struct AnalyticTexture {
  double wide_blob = 30, narrow_blob = 10;
  double operator()(double u, double v) const {
    return 1000 + 400 * std::exp(-((u - 5) * (u - 5) + (v + 3) * (v + 3)) / wide_blob) +
           300 * std::sin(0.35 * u + 0.1 * v) * std::cos(0.22 * v) +
           250 * std::exp(-((u + 8) * (u + 8) + (v - 6) * (v - 6)) / narrow_blob);
  }
};

// A w×h image with the target's centre at (cx, cy), turned by phi_deg (CCW on screen).
// add(x, y, value) returns the pixel's value after whatever the scene adds (clutter, noise).
template <class Add>
std::vector<std::uint16_t> render_analytic(int w, int h, double cx, double cy, double phi_deg, const AnalyticTexture& texture,
                                           Add add) {
  const double c = std::cos(phi_deg * M_PI / 180), s = std::sin(phi_deg * M_PI / 180);
  std::vector<std::uint16_t> out(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double dx = x - cx, dy = y - cy;
      const double v = add(x, y, texture(dx * c - dy * s, dx * s + dy * c));
      out[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.0, 65535.0)));
    }
  return out;
}

inline std::vector<std::uint16_t> render_analytic(int w, int h, double cx, double cy, double phi_deg,
                                                  const AnalyticTexture& texture = {}) {
  return render_analytic(w, h, cx, cy, phi_deg, texture, [](int, int, double v) { return v; });
}

}  // namespace sempose::test
