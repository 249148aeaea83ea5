// The one summed-area table of the pose engine: exact integer running sums of f and f² over a
// region ((h+1)×(w+1), first row and column zero), so the sum and the sum of squares over any
// rectangle cost four look-ups each, with no cancellation (Σf² − (Σf)²/n of a flat window is
// exactly 0). The FFT correlator normalises every displacement with it; the exact scorer takes
// each window's mean and variance from it. Construction is setup; build() and the look-ups are RT.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sempose::pose {

class SummedAreaTables {
 public:
  SummedAreaTables(int max_w, int max_h);

  // RT: the tables of a w×h region (row stride in elements); w, h at most the setup maxima.
  void build(const std::uint16_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept;
  void build(const std::int32_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept;

  int width() const noexcept { return w_; }
  int height() const noexcept { return h_; }
  std::size_t row_stride() const noexcept { return static_cast<std::size_t>(w_) + 1; }
  const std::int64_t* sums() const noexcept { return sum_.data(); }
  const std::int64_t* square_sums() const noexcept { return sum_sq_.data(); }
  std::int64_t total() const noexcept { return sum_[static_cast<std::size_t>(h_) * row_stride() + w_]; }
  std::int64_t total_squares() const noexcept { return sum_sq_[static_cast<std::size_t>(h_) * row_stride() + w_]; }

  // Adds Σf and Σf² over columns x0..x1 and rows y0..y1 (inclusive) to sum and square_sum.
  void add_rect(int x0, int y0, int x1, int y1, std::int64_t& sum, std::int64_t& square_sum) const noexcept {
    const std::size_t stride = row_stride();
    const std::size_t ya = static_cast<std::size_t>(y0) * stride, yb = static_cast<std::size_t>(y1 + 1) * stride;
    const std::size_t xa = static_cast<std::size_t>(x0), xb = static_cast<std::size_t>(x1 + 1);
    sum += sum_[yb + xb] - sum_[yb + xa] - sum_[ya + xb] + sum_[ya + xa];
    square_sum += sum_sq_[yb + xb] - sum_sq_[yb + xa] - sum_sq_[ya + xb] + sum_sq_[ya + xa];
  }

  std::size_t memory_bytes() const noexcept { return (sum_.size() + sum_sq_.size()) * sizeof(std::int64_t); }

 private:
  template <typename T>
  void build_impl(const T* pixels, int w, int h, std::ptrdiff_t stride) noexcept;

  int max_w_, max_h_;
  int w_ = 0, h_ = 0;
  std::vector<std::int64_t> sum_, sum_sq_;
};

}  // namespace sempose::pose
