#include "sempose/pose/summed_area_table.hpp"
#include "sempose/pose/simd_clones.hpp"

#include <algorithm>

namespace sempose::pose {

namespace {
using V8 = std::int64_t __attribute__((vector_size(64)));

// One row of both tables: the row's running sums of f and f² plus the row above (b1, b2),
// written from index 1 on (a1[0] = a2[0] = 0 are the caller's). The running sum is taken
// eight pixels at a time inside a vector (three shift-and-add steps, then the carry of the
// row so far): the scalar running sum was two dependent adds and two 8-byte stores per
// pixel, and the table build was the largest single cost of a tracked frame (perf,
// pose_speed_bench --profile 192). Integer arithmetic: the same sums, to the bit, as any
// order of adding them. Compiled for AVX-512, AVX2 and the baseline; __builtin_shufflevector
// (GCC ≥ 12 and clang alike, unlike GCC's __builtin_shuffle).
template <typename T>
SEMPOSE_CLONES void add_row(const T* __restrict row, int w, const std::int64_t* __restrict b1,
                            const std::int64_t* __restrict b2, std::int64_t* __restrict a1,
                            std::int64_t* __restrict a2) noexcept {
  typedef T VT __attribute__((vector_size(8 * sizeof(T))));
  const V8 zero = {};
  V8 c1 = {}, c2 = {};
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    VT in;
    __builtin_memcpy(&in, row + x, sizeof(VT));
    V8 v = __builtin_convertvector(in, V8);
    V8 q = v * v;
    v += __builtin_shufflevector(v, zero, 8, 0, 1, 2, 3, 4, 5, 6);
    q += __builtin_shufflevector(q, zero, 8, 0, 1, 2, 3, 4, 5, 6);
    v += __builtin_shufflevector(v, zero, 8, 8, 0, 1, 2, 3, 4, 5);
    q += __builtin_shufflevector(q, zero, 8, 8, 0, 1, 2, 3, 4, 5);
    v += __builtin_shufflevector(v, zero, 8, 8, 8, 8, 0, 1, 2, 3);
    q += __builtin_shufflevector(q, zero, 8, 8, 8, 8, 0, 1, 2, 3);
    v += c1;
    q += c2;
    c1 = __builtin_shufflevector(v, v, 7, 7, 7, 7, 7, 7, 7, 7);
    c2 = __builtin_shufflevector(q, q, 7, 7, 7, 7, 7, 7, 7, 7);
    V8 u1, u2;
    __builtin_memcpy(&u1, b1 + x + 1, sizeof(V8));
    __builtin_memcpy(&u2, b2 + x + 1, sizeof(V8));
    u1 += v;
    u2 += q;
    __builtin_memcpy(a1 + x + 1, &u1, sizeof(V8));
    __builtin_memcpy(a2 + x + 1, &u2, sizeof(V8));
  }
  std::int64_t r1 = c1[0], r2 = c2[0];
  for (; x < w; ++x) {
    const std::int64_t v = row[x];
    r1 += v;
    r2 += v * v;
    a1[x + 1] = r1 + b1[x + 1];
    a2[x + 1] = r2 + b2[x + 1];
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
    std::int64_t* a1 = s1 + (y + 1) * sw;
    std::int64_t* a2 = s2 + (y + 1) * sw;
    a1[0] = a2[0] = 0;
    add_row(px + y * stride, w, s1 + y * sw, s2 + y * sw, a1, a2);
  }
}

}  // namespace sempose::pose
