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
  ox_ = oy_ = 0;
  w_ = w;
  h_ = h;
  src_ = nullptr;
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

void SummedAreaTables::attach(const std::int32_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept {
  src_ = pixels;
  src_w_ = std::clamp(w, 0, max_w_);
  src_h_ = std::clamp(h, 0, max_h_);
  src_stride_ = stride;
  tabled_ = false;
  ox_ = oy_ = w_ = h_ = 0;
}

void SummedAreaTables::cover(int x0, int y0, int x1, int y1) noexcept {
  if (src_ == nullptr) return;
  if (!tabled_) {
    table_part(std::max(0, x0 - kCoverMargin), std::max(0, y0 - kCoverMargin), std::min(src_w_, x1 + 1 + kCoverMargin),
               y1 + 1);
  } else if (x0 < ox_ || x1 >= ox_ + w_ || y0 < oy_) {
    table_part(0, 0, src_w_, std::max(y1 + 1, oy_ + h_));
  }
  if (y1 >= oy_ + h_) add_rows(y1 + 1);
}

void SummedAreaTables::table_part(int x0, int y0, int x1, int y1) noexcept {
  ox_ = x0;
  oy_ = y0;
  w_ = x1 - x0;
  h_ = 0;
  tabled_ = true;
  const std::size_t sw = row_stride();
  for (std::size_t x = 0; x < sw; ++x) sum_[x] = sum_sq_[x] = 0;
  add_rows(y1);
}

void SummedAreaTables::add_rows(int y1) noexcept {
  y1 = std::min(y1, src_h_);
  const std::size_t sw = row_stride();
  std::int64_t* s1 = sum_.data();
  std::int64_t* s2 = sum_sq_.data();
  for (int y = oy_ + h_; y < y1; ++y) {
    const int r = y - oy_;
    std::int64_t* a1 = s1 + (r + 1) * sw;
    std::int64_t* a2 = s2 + (r + 1) * sw;
    a1[0] = a2[0] = 0;
    add_row(src_ + y * src_stride_ + ox_, w_, s1 + r * sw, s2 + r * sw, a1, a2);
  }
  h_ = std::max(h_, y1 - oy_);
}

}  // namespace sempose::pose
