#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/simd_clones.hpp"

#include <algorithm>

namespace sempose::pose {

Prefilter::Prefilter(int passes, int max_w, int max_h)
    : passes_(passes),
      max_w_(max_w),
      max_h_(max_h),
      a_(static_cast<std::size_t>(max_w) * max_h),
      b_(static_cast<std::size_t>(max_w) * kRingRows),
      row_(static_cast<std::size_t>(max_w) + 4) {}

namespace {
// 32-bit lanes throughout: a pass multiplies by 256 (16 horizontally, 16 vertically), so
// inputs kept under 2^20 before a pass stay under 2^28 — twice the lanes of 64-bit
// arithmetic, and the reason each pass rescales its output.
template <typename T>
SEMPOSE_CLONES void horizontal(const T* src, int w, std::int32_t* row, std::int32_t* out) noexcept {
  for (int x = 0; x < w; ++x) row[x + 2] = static_cast<std::int32_t>(src[x]);
  row[0] = row[1] = row[2];
  row[w + 2] = row[w + 3] = row[w + 1];
  for (int x = 0; x < w; ++x) out[x] = row[x] + 4 * row[x + 1] + 6 * row[x + 2] + 4 * row[x + 3] + row[x + 4];
}
SEMPOSE_CLONES void vertical_row(const std::int32_t* __restrict r0, const std::int32_t* __restrict r1,
                                 const std::int32_t* __restrict r2, const std::int32_t* __restrict r3,
                                 const std::int32_t* __restrict r4, int w, int shift, std::int32_t* __restrict o) noexcept {
  for (int x = 0; x < w; ++x) o[x] = (r0[x] + 4 * r1[x] + 6 * r2[x] + 4 * r3[x] + r4[x]) >> shift;
}
}  // namespace

double prefilter_dc_gain(int passes, int bits) noexcept {
  double gain = 1.0;
  int cur_bits = bits;
  for (int p = 0; p < passes; ++p) {
    const int shift = std::max(0, cur_bits + 8 - 20);
    cur_bits = std::min(20, cur_bits + 8);
    gain *= 256.0 / static_cast<double>(1 << shift);
  }
  return gain;
}

void Prefilter::apply(const std::uint16_t* src, int w, int h, std::ptrdiff_t stride, int bits,
                      std::int32_t* out) noexcept {
  w = std::min(w, max_w_);
  h = std::min(h, max_h_);
  if (passes_ == 0) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) out[y * w + x] = src[y * stride + x];
    return;
  }
  // Each pass's output is shifted back to at most 20 bits (the correlator's window sums and
  // the next pass both need that headroom); the last pass writes straight into out.
  // The horizontal rows go through a ring of kRingRows rows, each computed just before the
  // vertical pass first needs it: the rows stay in L1 (a whole horizontally filtered ROI was
  // written to and read back from L2; perf, pose_speed_bench --profile 192). Integer
  // arithmetic, the same values as any order. A later pass reads and writes a_ in place: the
  // output row y is written after the input rows up to y + 2 were filtered into the ring.
  int cur_bits = bits;
  for (int p = 0; p < passes_; ++p) {
    const int shift = std::max(0, cur_bits + 8 - 20);
    cur_bits = std::min(20, cur_bits + 8);
    std::int32_t* dst = p + 1 == passes_ ? out : a_.data();
    int next = 0;  // the next input row to filter horizontally
    const std::int32_t* r[5];
    for (int y = 0; y < h; ++y) {
      for (const int last = std::min(y + 2, h - 1); next <= last; ++next) {
        std::int32_t* ring = b_.data() + static_cast<std::size_t>(next % kRingRows) * w;
        if (p == 0) horizontal(src + next * stride, w, row_.data(), ring);
        else horizontal(a_.data() + static_cast<std::size_t>(next) * w, w, row_.data(), ring);
      }
      for (int k = 0; k < 5; ++k)
        r[k] = b_.data() + static_cast<std::size_t>(std::clamp(y + k - 2, 0, h - 1) % kRingRows) * w;
      vertical_row(r[0], r[1], r[2], r[3], r[4], w, shift, dst + static_cast<std::size_t>(y) * w);
    }
  }
}

PrefilterNoiseGain::PrefilterNoiseGain(int passes) {
  // The 1-D kernel of all passes: [1 4 6 4 1]/16 convolved with itself once per pass.
  std::vector<double> k{1.0};
  static constexpr double b[5] = {1 / 16.0, 4 / 16.0, 6 / 16.0, 4 / 16.0, 1 / 16.0};
  for (int pass = 0; pass < passes; ++pass) {
    std::vector<double> next(k.size() + 4, 0.0);
    for (std::size_t i = 0; i < k.size(); ++i)
      for (std::size_t j = 0; j < 5; ++j) next[i + j] += k[i] * b[j];
    k.swap(next);
  }
  lag_.assign(k.size(), 0.0);
  for (std::size_t d = 0; d < k.size(); ++d)
    for (std::size_t i = 0; i + d < k.size(); ++i) lag_[d] += k[i] * k[i + d];
}

void prefilter_pattern(float* p, int n, int passes) {
  std::vector<double> a(static_cast<std::size_t>(n) * n), b(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = p[i];
  static constexpr double k[5] = {1 / 16.0, 4 / 16.0, 6 / 16.0, 4 / 16.0, 1 / 16.0};
  for (int pass = 0; pass < passes; ++pass) {
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        double s = 0;
        for (int i = 0; i < 5; ++i) s += k[i] * a[y * n + std::clamp(x + i - 2, 0, n - 1)];
        b[y * n + x] = s;
      }
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        double s = 0;
        for (int i = 0; i < 5; ++i) s += k[i] * b[std::clamp(y + i - 2, 0, n - 1) * n + x];
        a[y * n + x] = s;
      }
  }
  for (std::size_t i = 0; i < a.size(); ++i) p[i] = static_cast<float>(a[i]);
}

}  // namespace sempose::pose
