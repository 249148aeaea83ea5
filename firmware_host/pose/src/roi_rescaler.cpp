#include "sempose/pose/roi_rescaler.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::pose {

RoiRescaler::RoiRescaler(int max_roi_px)
    : max_roi_px_(max_roi_px),
      out_(static_cast<std::size_t>(max_roi_px) * max_roi_px, 0),
      x0_(static_cast<std::size_t>(max_roi_px), 0),
      wx_(static_cast<std::size_t>(max_roi_px), 0) {}

const std::uint16_t* RoiRescaler::rescale(const std::uint16_t* px, int w, int h, std::ptrdiff_t stride, int bits,
                                          double scale) noexcept {
  w = std::min(w, max_roi_px_);
  h = std::min(h, max_roi_px_);
  // Fixed point: weights in 1/256, the result keeps 2 bits of the fraction (out_bits).
  auto split = [](double v, int size, std::int32_t& i0, std::int32_t& wt) {
    v = std::clamp(v, 0.0, static_cast<double>(size - 1));
    i0 = std::min(static_cast<std::int32_t>(v), size - 2);
    wt = static_cast<std::int32_t>(std::lround((v - i0) * 256.0));
  };
  if (w < 2 || h < 2) return px;
  for (int x = 0; x < w; ++x) split(to_raw(x, w, scale), w, x0_[static_cast<std::size_t>(x)], wx_[static_cast<std::size_t>(x)]);
  const int extra = out_bits(bits) - bits;  // 2, fewer for 15- and 16-bit input
  const std::int32_t cap = (1 << out_bits(bits)) - 1;
  for (int y = 0; y < h; ++y) {
    std::int32_t y0 = 0, wy = 0;
    split(to_raw(y, h, scale), h, y0, wy);
    const std::uint16_t* r0 = px + static_cast<std::ptrdiff_t>(y0) * stride;
    const std::uint16_t* r1 = r0 + stride;
    std::uint16_t* o = out_.data() + static_cast<std::size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      const std::int32_t i = x0_[static_cast<std::size_t>(x)], a = wx_[static_cast<std::size_t>(x)];
      const std::int32_t top = r0[i] * (256 - a) + r0[i + 1] * a;
      const std::int32_t bot = r1[i] * (256 - a) + r1[i + 1] * a;
      // (top·(256 − wy) + bot·wy) / 2^16 · 2^extra, rounded.
      const int sh = 16 - extra;
      const std::int64_t v =
          (static_cast<std::int64_t>(top) * (256 - wy) + static_cast<std::int64_t>(bot) * wy + (std::int64_t{1} << (sh - 1))) >> sh;
      o[x] = static_cast<std::uint16_t>(std::min<std::int64_t>(v, cap));
    }
  }
  return out_.data();
}

}  // namespace sempose::pose
