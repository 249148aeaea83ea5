// The simulated SEM's scene, built once at setup: the background and each target as float
// layers (0..1 brightness) already blurred by the beam's Gaussian PSF, so the per-frame work
// is only sampling, counting noise and quantisation.
// Targets are stored premultiplied (brightness·alpha and alpha, both blurred): compositing
// blur(bg)·(1 − blur(α)) + blur(t·α) is exact where the background is locally flat and a close
// approximation elsewhere, and it lets a rotated target be sampled without re-blurring.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sempose/config/scan_config.hpp"
#include "sempose/config/sim_config.hpp"
#include "sempose/hal/image.hpp"

namespace sempose::hal {

struct FloatImage {
  std::int32_t w = 0, h = 0;
  std::vector<float> v;  // row-major
  float at(std::int32_t x, std::int32_t y) const noexcept { return v[static_cast<std::size_t>(y) * w + x]; }
};

struct SimLayer {
  bool enabled = false;
  FloatImage premul;  // brightness · alpha, PSF-blurred, with a border of pad pixels
  FloatImage alpha;   // mask, PSF-blurred
  double cx = 0, cy = 0;  // the pose point (texture centre) in layer pixels
  double radius = 0;      // from the centre to the farthest layer corner
};

class SimScene {
 public:
  // Setup: loads and crops textures, builds masks and procedural shapes, blurs. Throws
  // std::runtime_error naming the file or key and the problem.
  SimScene(const config::SimConfig& cfg, const config::ScanLimits& limits);

  const config::SimConfig& config() const noexcept { return cfg_; }
  const FloatImage& background() const noexcept { return background_; }
  const std::vector<SimLayer>& targets() const noexcept { return targets_; }

 private:
  config::SimConfig cfg_;
  FloatImage background_;
  std::vector<SimLayer> targets_;
};

// Setup helpers (also used by tests).
// The data file `path` (absolute, or relative to the data folders of config/data_path.hpp);
// throws naming `what`, the path and every place tried if it is missing or unusable.
std::string resolve_data_path(const std::string& path, const std::string& what);
void gaussian_blur(FloatImage& img, double sigma);
// Bilinear resample to w x h.
FloatImage resample(const FloatImage& src, std::int32_t w, std::int32_t h);
// Crop of an image as 0..1 floats (divided by 255 or 65535); throws when the crop is outside.
FloatImage crop_to_float(const Image& img, std::int32_t x, std::int32_t y, std::int32_t w, std::int32_t h,
                         const std::string& what);

}  // namespace sempose::hal
