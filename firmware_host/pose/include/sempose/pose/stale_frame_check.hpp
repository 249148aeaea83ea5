// A frame that repeats the last one this tracker saw, pixel for pixel, where the scene cannot have
// stayed the same: a frozen frame buffer, a DMA block not refilled, a recording with a frame
// stored twice. Tracked as if new, the old image at a moved ROI reads as the target's move and the
// ROI follows it, or at the same ROI holds the pose while the target moves on (pose_envelope_probe
// frozen_frames_40_49 on 7e87312: TRACKING up to 190 px off). Two real scans never agree on
// thousands of noisy pixels; the same pixels can only be right for a still target in a noise-free
// (synthetic) frame at the same place, so a repeat counts when it was scanned elsewhere or the
// stream expected the target to move (the caller says which).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sempose::pose {

class StaleFrameCheck {
 public:
  // Every kSampleStride-th pixel in raster order (7: prime to the row lengths, so the samples
  // walk across columns) is kept: 1/7 of a copy's cost and still ~5000 samples at 192².
  static constexpr int kSampleStride = 7;

  // max_pixels: the largest frame it will be shown (the scan field); larger ones are not checked.
  explicit StaleFrameCheck(std::size_t max_pixels) : samples_(max_pixels / kSampleStride + 1, 0) {}

  // True when this w × h frame at (x, y) in the field repeats the previous one at every sample,
  // is not flat (a blank or saturated frame has its own reason), and either the previous one was
  // scanned elsewhere or expects_change (the stream predicted a move since). Remembers this
  // frame's samples and place. No allocation.
  bool repeats(const std::uint16_t* px, int x, int y, int w, int h, bool expects_change) noexcept {
    const std::size_t n_px = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    const std::size_t n = (n_px + kSampleStride - 1) / kSampleStride;
    if (w <= 0 || h <= 0 || n > samples_.size()) {
      w_ = h_ = 0;
      return false;
    }
    bool same = w == w_ && h == h_ && (expects_change || x != x_ || y != y_);
    std::uint16_t lo = px[0], hi = px[0];
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint16_t v = px[i * kSampleStride];
      same &= v == samples_[i];
      samples_[i] = v;
      lo = v < lo ? v : lo;
      hi = v > hi ? v : hi;
    }
    x_ = x;
    y_ = y;
    w_ = w;
    h_ = h;
    return same && hi > lo;
  }

 private:
  std::vector<std::uint16_t> samples_;
  int x_ = 0, y_ = 0, w_ = 0, h_ = 0;
};

}  // namespace sempose::pose
