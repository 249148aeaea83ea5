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
#include "sempose/hal/frame.hpp"
#include "sempose/hal/image.hpp"

namespace sempose::hal {

struct FloatImage {
  std::int32_t w = 0, h = 0;
  std::vector<float> v;  // row-major
  float at(std::int32_t x, std::int32_t y) const noexcept { return v[static_cast<std::size_t>(y) * w + x]; }
};

// One rigid piece of a target. A gripper whose jaws move has three (body, upper jaw, lower
// jaw: the jaws slide along the target's own y axis); every other target has one.
struct SimPart {
  FloatImage premul;  // brightness · alpha, PSF-blurred, with a border of pad pixels
  FloatImage alpha;   // mask, PSF-blurred
  float jaw_dir = 0;  // 0: fixed to the body; −1 / +1: moves by ∓/± the jaw opening along texture y
};

struct SimLayer {
  bool enabled = false;
  std::vector<SimPart> parts;  // all the same size, sharing the centre below
  double cx = 0, cy = 0;  // the pose point (texture centre) in layer pixels
  double radius = 0;      // from the centre to the farthest layer corner (at scale 1)
  std::int32_t w() const noexcept { return parts.empty() ? 0 : parts[0].alpha.w; }
  std::int32_t h() const noexcept { return parts.empty() ? 0 : parts[0].alpha.h; }
};

// A target's pose and shape at one instant (the simulator evaluates it per scan line).
struct SimTargetPose {
  bool active = true;
  double x_px = 0, y_px = 0, phi_deg = 0;
  double scale = 1.0;        // size relative to the configured one
  double jaw_open_px = 0.0;  // gripper jaws: opening per jaw (texture px)
};

// The per-line form of a SimTargetPose, as the compositing loop uses it.
struct LinePose {
  bool active = false;
  double cx = 0, cy = 0;  // pose point on the field
  double c = 1, s = 0;    // cos φ / scale, sin φ / scale: field offset -> texture offset
  float jaw = 0;          // jaw opening, texture px
};

class SimScene {
 public:
  // Setup: loads and crops textures, builds masks and procedural shapes, blurs. Throws
  // std::runtime_error naming the file or key and the problem.
  SimScene(const config::SimConfig& cfg, const config::ScanLimits& limits);

  const config::SimConfig& config() const noexcept { return cfg_; }
  const FloatImage& background() const noexcept { return background_; }
  const std::vector<SimLayer>& targets() const noexcept { return targets_; }

  // Per line: target t at pose p as seen by a line at field row qy (inactive when the line
  // misses it). RT-safe.
  LinePose line_pose(std::size_t t, const SimTargetPose& p, float qy) const noexcept;
  // The scene's mean brightness along one line, before the detector: the background at
  // (qx0 + i − lag(i), qy), every active target composited over it. lag(i) = lag[i + lag_offset]
  // where that index is inside [0, lag_n), else 0. coverage (may be null): the largest target
  // alpha per pixel. RT-safe (SimSource::render calls it for every line).
  void compose_line(const LinePose* poses, float qx0, float qy, const float* lag, int lag_n, int lag_offset, int n,
                    float* out, float* coverage) const noexcept;
  // The noise-free mean of roi with every target at poses[t] (one per target; disabled targets
  // stay off): no drift, line jitter or beam lag; brightness b -> max(0, gain·b + offset), then
  // an extra Gaussian blur of defocus_px. Mean electrons = out × electrons_per_pixel(dwell);
  // counts = output_offset·max + electrons × output_white·max / electrons_per_pixel(dwell).
  // coverage (optional): the targets' alpha, blurred the same way — the pixels they affect.
  // Allocates: tests, benchmarks (the Cramér–Rao bound), setup.
  void render_mean(const Roi& roi, const SimTargetPose* poses, double gain, double offset, double defocus_px,
                   std::vector<float>& out, std::vector<float>* coverage = nullptr) const;

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
// The same blur on a w×h buffer in place, edges clamped, without allocating (tmp: w·h floats);
// sigma up to kMaxBlurSigma. RT-safe (the simulator's defocus).
inline constexpr double kMaxBlurSigma = 10.0;
void gaussian_blur_in_place(float* img, int w, int h, double sigma, float* tmp) noexcept;
// Bilinear resample to w x h.
FloatImage resample(const FloatImage& src, std::int32_t w, std::int32_t h);
// Crop of an image as 0..1 floats (divided by 255 or 65535); throws when the crop is outside.
FloatImage crop_to_float(const Image& img, std::int32_t x, std::int32_t y, std::int32_t w, std::int32_t h,
                         const std::string& what);

}  // namespace sempose::hal
