// Learned appearance, the RT half: after a good tracked frame, the loaded (prefiltered) ROI is
// sampled in the pattern's own frame at the measured pose, gain and offset against the
// recorded pattern are fitted, and per pattern pixel the squared residual and the observation
// (in pattern units) are summed, with the frame's detector noise (Immerkær's estimator on the
// raw window, through the prefilter's noise gain). Each frame samples one row in eight of the
// pattern (the phase turning per frame): the RT cost is an eighth of a full pass, and over a
// batch every row is seen alike.
// frames_per_update frames make a batch,
// handed to the non-RT side (AppearanceModel, via Tracker::maintain_appearance) through a
// two-buffer exchange: the RT side fills one buffer while the other is with the worker; an
// atomic index says which one is handed over (release/acquire), nothing waits: a batch
// completed while the worker still holds the other keeps growing until it is free.
// Construction is setup; observe() / discard() are RT (noexcept, no allocation); take() /
// give_back() are the worker's.
#pragma once

#include <atomic>
#include <limits>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace sempose::pose {

// Sums over observed frames in the pattern's frame (size_px², row-major).
struct AppearanceStats {
  int size_px = 0;
  std::uint8_t set = 0;            // the pattern set observed
  int frames = 0;
  double sum_noise_var = 0;        // Σ per-frame detector noise variance (pattern units, prefiltered)
  std::vector<double> sum_r2;      // Σ (f − a·t − b)² / a² per pixel
  std::vector<double> sum_obs;     // Σ (f − b) / a per pixel: the aligned observation
  std::vector<std::uint32_t> hits; // frames that saw the pixel
  // The batch's poses on the background (field pixels; the angle relative to the batch's first
  // frame, wrapped): how far the target moved over it (the template refinement's gate).
  double sum_fx = 0, sum_fy = 0, sum_fxx = 0, sum_fyy = 0, sum_dphi = 0, sum_dphi2 = 0, phi0_deg = 0;

  explicit AppearanceStats(int n = 0);
  // RMS spread of the frames' field positions about their mean, plus the angle's RMS spread
  // (radians) × radius_px, the movement of a point at that radius (pixels).
  double motion_spread_px(double radius_px) const noexcept;
  void clear() noexcept;
  // Adds another batch of the same size (the worker's running total).
  void add(const AppearanceStats& o) noexcept;
  std::size_t memory_bytes() const noexcept;
};

class AppearanceObserver {
 public:
  // inside: the pattern's support bitmap (size_px²; the fine circle), the pixels observed.
  AppearanceObserver(int size_px, const std::uint8_t* inside, int frames_per_batch, double prefilter_noise_gain,
                     int prefilter_passes);
  // Setup: pattern set k's recorded pattern, prefiltered like the frames (size_px², float).
  void add_reference(std::vector<float> prefiltered);

  // RT: one good frame. roi: prefiltered ROI minus its mean (w×h, stride w); raw: the same
  // ROI's pixels (stride raw_stride, `bits` bits); (cx, cy): the pattern centre in ROI pixels,
  // phi_deg its angle; (field_x, field_y): the same centre in the scan field (how far it moved
  // over the background; NaN: the ROI's (cx, cy)). False when the frame was not used (pattern
  // outside the ROI, flat, inverted contrast).
  bool observe(std::uint8_t set, const float* roi, int w, int h, const std::uint16_t* raw, std::ptrdiff_t raw_stride,
               int bits, double cx, double cy, double phi_deg, double field_x = std::numeric_limits<double>::quiet_NaN(),
               double field_y = std::numeric_limits<double>::quiet_NaN()) noexcept;
  // RT: the target was lost or the pattern set changed: the batch being filled is dropped.
  void discard() noexcept;

  // Worker: a completed batch, or nullptr. Hand it back with give_back() when done.
  const AppearanceStats* take() noexcept;
  void give_back() noexcept;

  int size_px() const noexcept { return n_; }
  const std::vector<float>& reference(std::uint8_t set) const { return refs_[set]; }
  std::size_t memory_bytes() const noexcept;

 private:
  // Rows of the pattern's frame observed per frame: one in kRowPhases (RT cost / 8).
  static constexpr int kRowPhases = 8;
  double window_noise_var(const std::uint16_t* raw, std::ptrdiff_t stride, int x0, int y0, int size,
                          int phase) const noexcept;

  int n_;
  std::vector<std::uint8_t> inside_;
  int frames_per_batch_;
  double noise_gain_;   // Σk² of the 2-D prefilter kernel
  int passes_;
  std::vector<std::vector<float>> refs_;
  std::vector<float> sampled_;     // this frame's samples (size_px²)
  AppearanceStats buf_[2];
  int filling_ = 0;
  int phase_ = 0;                  // the row phase of the next observed frame
  std::atomic<int> handed_{-1};    // the buffer with the worker, -1: none
};

}  // namespace sempose::pose
