// The simulated SEM (YAML section `sim:`) and the replay source (section `replay:`).
// Defaults make a usable simulation with no `sim:` section at all: a 1024x768 field, a needle
// tip textured from the real SEM image data/sem/needle_contact_eb.pgm (config/data/sem; its last
// 120 px at 3/4 scale, so a 128 px pattern holds its outline) moving on a slow sine, a
// procedural gripper as a second (disabled) target, and a beam dose that gives
// single-digit detected electrons per pixel at 250 ns dwell (README: The simulated SEM).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sempose::config {

class Section;

// A quantity over time (t in seconds since the source started): `from` until start_s, then a
// straight ramp to `to` over ramp_s seconds (0: a step at start_s), held after; plus
// amplitude·sin(2π·t / period_s). Scale, jaw opening, charging gain/offset and defocus use it.
struct TimeProfile {
  double from = 0, to = 0;
  double start_s = 0, ramp_s = 0;
  double amplitude = 0, period_s = 1;

  static TimeProfile constant(double v) noexcept {
    TimeProfile p;
    p.from = p.to = v;
    return p;
  }
  bool is_constant() const noexcept { return from == to && amplitude == 0; }
  // The largest |value| the profile can take (buffers and padding are sized for it at setup).
  double max_abs() const noexcept {
    return (std::fabs(from) > std::fabs(to) ? std::fabs(from) : std::fabs(to)) + std::fabs(amplitude);
  }
  double at(double t_s) const noexcept {
    double v = from;
    if (t_s >= start_s) {
      const double f = ramp_s > 0 ? (t_s - start_s) / ramp_s : 1.0;
      v = from + (to - from) * (f < 1.0 ? f : 1.0);
    }
    if (amplitude != 0) v += amplitude * std::sin(6.283185307179586 * t_s / period_s);
    return v;
  }
};

// x(t), y(t), φ(t) of one target; t in seconds since the source started.
struct TrajectoryConfig {
  // static | linear | sine | steps | jumps | spin | random_walk
  std::string kind = "static";
  // linear: velocity (bounces off the bounds); spin: omega_deg_s only.
  double vx_px_s = 0, vy_px_s = 0, omega_deg_s = 0;
  // sine: amplitudes and period; steps: the step size per period; jumps: the φ range (±).
  double amplitude_x_px = 0, amplitude_y_px = 0, amplitude_phi_deg = 0;
  double period_s = 1.0;
  int steps = 4;  // steps: a staircase of this many steps, then back down
  // random_walk: diffusion per √s, knots every knot_s, bounded by the bounds.
  double sigma_px_per_sqrt_s = 4.0, sigma_deg_per_sqrt_s = 2.0, knot_s = 0.05;
  // Bounds for linear/jumps/random_walk: the field minus this margin.
  double margin_px = 96;
  bool margin_given = false;  // margin_px came from the config (check_sim_room judges it)
};

// Where a texture comes from: a crop of a PGM image or a procedural shape.
struct TextureConfig {
  std::string source = "image";  // image | gripper | lamella
  std::string path;              // image: PGM path (relative: to cwd, then to the repo root)
  std::int32_t crop_x = 0, crop_y = 0, crop_w = 0, crop_h = 0;  // 0 size: the whole image
  // image mask: full (the crop rectangle) | threshold (largest bright region of the crop) |
  // threshold_all (every bright region of >= 5 % of the largest: a needle with the lamella it carries)
  std::string mask = "full";
  double mask_level = 0.6;  // threshold mask: brightness 0..1 on the smoothed texture
};

struct SimTargetConfig {
  bool enabled = true;
  TextureConfig texture;
  std::int32_t width_px = 0, height_px = 0;  // size on the field; 0: the crop's size
  double brightness = 1.0;                   // multiplies the texture (0..1 scene brightness)
  double x_px = 512, y_px = 384, phi_deg = 0;  // pose at t = 0 (README: Conventions)
  TrajectoryConfig trajectory;
  // Size on the field relative to size_px over time (a magnification ramp or a working
  // distance change), about the pose point; 1 = as configured.
  TimeProfile scale = TimeProfile::constant(1.0);
  // Procedural gripper only: each jaw's opening in px over time, outward from the rest
  // position (negative: closing); the body, which carries the pose point, does not move.
  TimeProfile jaws = TimeProfile::constant(0.0);
};

// At most this many drift terms: each is summed for every scanned line (RT path).
constexpr std::size_t kMaxDriftTerms = 16;

struct DriftTerm {  // one sinusoid of the slow image drift
  double amplitude_px = 0, period_s = 10, direction_deg = 0, phase_deg = 0;
};

struct SimBackgroundConfig {
  std::string source = "procedural";  // procedural | image
  std::string path;                   // image: PGM, cropped then resampled to the field
  std::int32_t crop_x = 0, crop_y = 0, crop_w = 0, crop_h = 0;
  double mean = 0.30, contrast = 0.12;  // procedural: grey level and granular contrast (0..1)
  double grain_px = 2.5;                // procedural: size of the surface grains
};

struct SimConfig {
  std::uint64_t seed = 1;
  std::string clock = "real";  // real (CLOCK_MONOTONIC) | virtual (deterministic)
  bool noise = true;           // false: expected values, no jitter (geometry tests)
  // Give each simulated target's tracker its shape mask (the target's outline, as an operator
  // would draw it); off by default: it helps at >= 6 e-/px on cluttered ground, hurts below.
  bool use_shape_masks = false;
  // Counting law: n = 6.24 · I[pA] · τ[µs] · η electrons for brightness 1.
  double beam_current_pa = 50.0;
  double yield = 0.10;              // η: SE yield × detector efficiency
  double detector_gain_shape = 3.0;  // k of the Gamma gain per electron (excess noise 1 + 1/k)
  double read_noise_e = 0.3;         // Gaussian read noise, in electrons
  double output_offset = 0.04;       // black level, fraction of full scale
  double output_white = 0.85;        // brightness 1 at mean gain, fraction of full scale
  double psf_sigma_px = 0.8;         // Gaussian beam spot
  double line_jitter_px = 0.15;      // σ of a random horizontal shift per line
  double beam_lag_px = 1.5;          // position lag at line start ...
  double beam_lag_len_px = 3.0;      // ... decaying over this many pixels
  std::vector<DriftTerm> drift{{0.4, 23.0, 30.0, 0.0}, {0.25, 7.0, 120.0, 90.0}};
  double brightness_drift = 0.03;        // relative amplitude (charging)
  double brightness_drift_period_s = 40.0;
  // Charging steps and ramps: scene brightness b becomes gain(t)·b + offset(t) before the
  // detector (so the electron count and its noise follow). Off: gain 1, offset 0.
  TimeProfile charging_gain = TimeProfile::constant(1.0);
  TimeProfile charging_offset = TimeProfile::constant(0.0);
  // Defocus: an extra Gaussian blur of this σ (px) on top of psf_sigma_px, over time (taken
  // at each frame's mid-scan). Off: 0.
  TimeProfile defocus_px = TimeProfile::constant(0.0);
  // Detector bandwidth: time constant of a first-order low-pass on the signal along each line
  // (the scintillator/PMT/amplifier chain). An edge lags e^(−d/τ)/(1 − e^(−d/τ)) pixels at dwell d:
  // 120 ns gives 0.77 px at 100 ns dwell, 0.14 px at 250 ns. 0: infinite bandwidth (off).
  double detector_tau_ns = 0.0;
  SimBackgroundConfig background;
  std::vector<SimTargetConfig> targets = default_targets();

  static std::vector<SimTargetConfig> default_targets();
  double electrons_per_pixel(std::uint32_t dwell_ns) const noexcept {
    return 6.24 * beam_current_pa * (dwell_ns * 1e-3) * yield;
  }
};

struct ReplayConfig {
  std::string frames_dir;      // directory of full-field PGM frames (+ frames.csv)
  bool loop = false;           // at the end: start again (true) or report kEnded
  std::string clock = "virtual";  // virtual | real (poll busy until the scan time passed)
};

void read_sim(Section& section, SimConfig& out);
// The simulator's image textures and background given by a relative path, resolved as
// data_path.hpp says, beside config_path first (the file that names them). One not found is an
// error at its key under root when required (`sempose sim`, or `run` with the simulator as its
// source); otherwise it is left as written.
void resolve_sim_data(Section& root, const std::string& config_path, SimConfig& sim, bool required);
// A trajectory margin_px the config gives that leaves its target no room to move on an axis of
// the field_w x field_h field (the bounds meet: the target pinned there) is an error at its key.
void check_sim_room(Section& root, const SimConfig& sim, int field_w, int field_h);
void read_replay(Section& section, ReplayConfig& out);

}  // namespace sempose::config
