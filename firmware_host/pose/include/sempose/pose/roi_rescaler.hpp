// Scale as a tracked degree of freedom (issue 13 item 2): the raw ROI resampled by 1/scale
// about its centre, so that a target seen `scale` times the pattern's size reaches the FFT
// peak, the walk and the fit at the pattern's own size — the whole engine keeps one bank.
// Bilinear (a target's scale changes by a few % per second; the blur this adds is far below
// the prefilter's); 2 extra bits keep the interpolated fraction. Setup allocates; rescale()
// is RT.
#pragma once


#include <cstddef>
#include <cstdint>
#include <vector>

namespace sempose::pose {

class RoiRescaler {
 public:
  // Closer to 1 than this, a ROI is loaded as scanned. Resampling costs ~40 µs, and at 1 %
  // its interpolation blur cost more angle accuracy than the size error it removes
  // (pose_accuracy_bench).
  static constexpr double kMinChange = 0.025;

  explicit RoiRescaler(int max_roi_px);

  // RT: out(x', y') = in(c + scale·((x', y') − c)), c the ROI's centre, samples outside
  // clamped to the border; w, h cut to max_roi_px. Returns the resampled ROI (row stride w,
  // `bits + 2` significant bits).
  const std::uint16_t* rescale(const std::uint16_t* px, int w, int h, std::ptrdiff_t stride, int bits,
                               double scale) noexcept;
  static int out_bits(int bits) noexcept { return bits + 2 > 16 ? 16 : bits + 2; }

  // Where a point of the resampled ROI lies in the raw one (and back), ROI coordinates.
  static double to_raw(double v, int size, double scale) noexcept { return (size - 1) / 2.0 + scale * (v - (size - 1) / 2.0); }

  std::size_t memory_bytes() const noexcept { return out_.size() * sizeof(std::uint16_t); }

 private:
  int max_roi_px_;
  std::vector<std::uint16_t> out_;
  std::vector<std::int32_t> x0_;  // per output column: left source column, weight ×256
  std::vector<std::int32_t> wx_;
};

}  // namespace sempose::pose
