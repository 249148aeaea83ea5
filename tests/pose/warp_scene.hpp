// A simulator-free ground truth for the tracker's geometry: a real SEM image seen through a
// Gaussian PSF is the continuous scene (sampled in closed form, so no interpolation error); the pattern is an integer crop of it; a frame shows that crop placed at an exact
// sub-pixel pose (x, y, φ) in the the README's conventions: pattern pixel ((P−1)/2, (P−1)/2)
// lands on (x, y), rotated counter-clockwise on the screen by φ. Optional Poisson noise at
// a dose in electrons per pixel. Test/benchmark helper only (allocates).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "sempose/hal/frame.hpp"
#include "sempose/hal/image.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/trajectory.hpp"

namespace sempose::pose::testing {

struct WarpScene {
  int w = 0, h = 0;
  double sigma = 1.0;
  std::vector<float> v;  // the raw image, 0..1 brightness

  // The continuous scene: the image's pixels as points, each spread by a Gaussian PSF of
  // sigma_px. Sampled anywhere in closed form (no interpolation error), so shifted and
  // rotated frames are exact.
  static WarpScene load(const std::string& path, double sigma_px) {
    const hal::Image img = hal::read_pgm(path);
    WarpScene s;
    s.w = img.width;
    s.h = img.height;
    s.sigma = sigma_px;
    s.v.resize(img.pixels.size());
    const float scale = img.bits > 8 ? 1.0f / 65535.0f : 1.0f / 255.0f;
    for (std::size_t i = 0; i < s.v.size(); ++i) s.v[i] = img.pixels[i] * scale;
    return s;
  }

  float at(int x, int y) const noexcept {
    return v[static_cast<std::size_t>(std::clamp(y, 0, h - 1)) * w + std::clamp(x, 0, w - 1)];
  }

  double sample(double x, double y) const noexcept {
    const int r = static_cast<int>(std::ceil(3 * sigma));
    const int ix = static_cast<int>(std::lround(x)), iy = static_cast<int>(std::lround(y));
    double wx[64], wy[64], sx = 0, sy = 0;
    const double k = -0.5 / (sigma * sigma);
    for (int i = -r; i <= r; ++i) {
      sx += wx[i + r] = std::exp(k * (ix + i - x) * (ix + i - x));
      sy += wy[i + r] = std::exp(k * (iy + i - y) * (iy + i - y));
    }
    double acc = 0;
    for (int j = -r; j <= r; ++j) {
      double row = 0;
      for (int i = -r; i <= r; ++i) row += wx[i + r] * at(ix + i, iy + j);
      acc += wy[j + r] * row;
    }
    return acc / (sx * sy);
  }

  // The P×P pattern whose centre pixel ((P−1)/2, (P−1)/2) is scene point (cx, cy); cx − (P−1)/2
  // must be an integer (an exact crop). 16-bit grey levels.
  hal::Image pattern(double cx, double cy, int P) const {
    hal::Image im;
    im.width = im.height = P;
    im.bits = 16;
    im.pixels.resize(static_cast<std::size_t>(P) * P);
    const int x0 = static_cast<int>(std::lround(cx - (P - 1) / 2.0)), y0 = static_cast<int>(std::lround(cy - (P - 1) / 2.0));
    for (int y = 0; y < P; ++y)
      for (int x = 0; x < P; ++x) im.pixels[static_cast<std::size_t>(y) * P + x] = to_level(sample(x0 + x, y0 + y));
    return im;
  }

  // A fw×fh field showing scene point (cx, cy) at (x, y), turned by phi_deg CCW on screen.
  // dose_e > 0: Poisson electrons per pixel at brightness 1 (mean kept), else noise-free.
  // roi: render only that part of the field (out is roi.w × roi.h); default: the whole field.
  void render(double cx, double cy, double x, double y, double phi_deg, int fw, int fh, std::vector<hal::Pixel>& out,
              double dose_e = 0, std::uint64_t seed = 1, hal::Roi roi = {}) const {
    render_rows(cx, cy, [&](int) { return hal::Pose2{x, y, phi_deg}; }, fw, fh, out, dose_e, seed, roi);
  }
  // As render(), the target's pose per row (pose_of_row(py)): a raster scan of a moving target.
  template <class PoseOfRow>
  void render_rows(double cx, double cy, const PoseOfRow& pose_of_row, int fw, int fh, std::vector<hal::Pixel>& out,
                   double dose_e = 0, std::uint64_t seed = 1, hal::Roi roi = {}) const {
    if (roi.w <= 0 || roi.h <= 0) roi = {0, 0, fw, fh};
    out.resize(static_cast<std::size_t>(roi.w) * roi.h);
    std::mt19937_64 rng(seed);
    for (int py = roi.y; py < roi.y + roi.h; ++py) {
      const hal::Pose2 pose = pose_of_row(py);
      const double x = pose.x_px, y = pose.y_px;
      const double rad = pose.phi_deg * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
      for (int px = roi.x; px < roi.x + roi.w; ++px) {
        // Inverse of the CCW screen rotation (same formula as rotate_pattern and the simulator).
        const double dx = px - x, dy = py - y;
        double b = sample(cx + dx * cs - dy * sn, cy + dx * sn + dy * cs);
        if (dose_e > 0) {
          std::poisson_distribution<int> p(std::max(0.0, b) * dose_e);
          b = p(rng) / dose_e;
        }
        out[static_cast<std::size_t>(py - roi.y) * roi.w + (px - roi.x)] = to_level(b);
      }
    }
  }

  static hal::Pixel to_level(double b) noexcept {
    return static_cast<hal::Pixel>(std::clamp(std::lround(b * 0.5 * 65535.0) + 2048, 0L, 65535L));
  }
};

// Crops roi out of a full field (row stride fw).
inline void crop(const std::vector<hal::Pixel>& field, int fw, const hal::Roi& roi, std::vector<hal::Pixel>& out) {
  out.resize(static_cast<std::size_t>(roi.w) * roi.h);
  for (int y = 0; y < roi.h; ++y)
    std::copy_n(field.begin() + static_cast<std::ptrdiff_t>(roi.y + y) * fw + roi.x, roi.w,
                out.begin() + static_cast<std::ptrdiff_t>(y) * roi.w);
}

}  // namespace sempose::pose::testing
