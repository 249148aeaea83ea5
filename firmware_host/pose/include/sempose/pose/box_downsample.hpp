// The one box downsample of the pose engine: every output pixel is the plain sum of a
// factor×factor block of the source (the caller scales if it wants a mean). Used for the
// 2×2-binned ROI (half-resolution FFT level), the ×8 full-field frame (start search) and the
// binned and coarse pattern copies (setup). Sums run row by row, left to right, in Sum: for
// integers the order does not matter, for float patterns the order is fixed here once.
#pragma once

#include <cstddef>

namespace sempose::pose {

// out[out_h][out_w] (row stride out_w) = block sums of src starting at (x0, y0), row stride
// src_stride. The caller guarantees the blocks lie inside src.
template <typename Source, typename Sum, typename Out>
void box_downsample(const Source* src, std::ptrdiff_t src_stride, int x0, int y0, int factor, int out_w, int out_h,
                    Out* out) noexcept {
  for (int y = 0; y < out_h; ++y) {
    for (int x = 0; x < out_w; ++x) {
      Sum acc = 0;
      for (int j = 0; j < factor; ++j) {
        const Source* row = src + static_cast<std::ptrdiff_t>(y0 + y * factor + j) * src_stride + x0 + x * factor;
        for (int i = 0; i < factor; ++i) acc += row[i];
      }
      out[static_cast<std::ptrdiff_t>(y) * out_w + x] = static_cast<Out>(acc);
    }
  }
}

}  // namespace sempose::pose
