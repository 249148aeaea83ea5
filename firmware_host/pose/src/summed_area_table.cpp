#include "sempose/pose/summed_area_table.hpp"
#include "sempose/pose/simd_clones.hpp"

#include <algorithm>

namespace sempose::pose {

namespace {
// Each row is its own running sum plus the row above: the add over the row vectorises (the
// running sum along the row cannot), compiled for AVX-512, AVX2 and the baseline.
SEMPOSE_CLONES void add_rows(
    std::int64_t* __restrict a1, const std::int64_t* __restrict b1, std::int64_t* __restrict a2,
    const std::int64_t* __restrict b2, int n) noexcept {
  for (int x = 0; x < n; ++x) {
    a1[x] += b1[x];
    a2[x] += b2[x];
  }
}
}  // namespace

SummedAreaTables::SummedAreaTables(int max_w, int max_h)
    : max_w_(max_w),
      max_h_(max_h),
      sum_(static_cast<std::size_t>(max_w + 1) * (max_h + 1), 0),
      sum_sq_(sum_.size(), 0) {}

void SummedAreaTables::build(const std::uint16_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept {
  build_impl(pixels, w, h, stride);
}
void SummedAreaTables::build(const std::int32_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept {
  build_impl(pixels, w, h, stride);
}

template <typename T>
void SummedAreaTables::build_impl(const T* px, int w, int h, std::ptrdiff_t stride) noexcept {
  w = std::clamp(w, 0, max_w_);
  h = std::clamp(h, 0, max_h_);
  w_ = w;
  h_ = h;
  const std::size_t sw = row_stride();
  std::int64_t* s1 = sum_.data();
  std::int64_t* s2 = sum_sq_.data();
  for (std::size_t x = 0; x < sw; ++x) s1[x] = s2[x] = 0;
  for (int y = 0; y < h; ++y) {
    const T* row = px + y * stride;
    std::int64_t r1 = 0, r2 = 0;
    std::int64_t* a1 = s1 + (y + 1) * sw;
    std::int64_t* a2 = s2 + (y + 1) * sw;
    const std::int64_t* b1 = s1 + y * sw;
    const std::int64_t* b2 = s2 + y * sw;
    a1[0] = a2[0] = 0;
    for (int x = 0; x < w; ++x) {
      const std::int64_t v = row[x];
      r1 += v;
      r2 += v * v;
      a1[x + 1] = r1;
      a2[x + 1] = r2;
    }
    add_rows(a1 + 1, b1 + 1, a2 + 1, b2 + 1, w);
  }
}

}  // namespace sempose::pose
