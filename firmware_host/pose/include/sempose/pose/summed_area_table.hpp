// The one summed-area table of the pose engine: exact integer running sums of f and f² over a
// region ((h+1)×(w+1), first row and column zero), so the sum and the sum of squares over any
// rectangle cost four look-ups each, with no cancellation (Σf² − (Σf)²/n of a flat window is
// exactly 0). The FFT correlator normalises every displacement with it; the exact scorer takes
// each window's mean and variance from it, tabling on demand only the part of the ROI its
// windows cover (attach() and cover()). Construction is setup; build(), cover() and the
// look-ups are RT.
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

  // RT, on demand: remembers a w×h region (row stride in elements; the pixels must stay as
  // they are until the next attach or build) and tables nothing yet. cover() then tables the
  // part that rectangles are about to be read from. The exact scorer reads a few windows
  // around one pose, ~half of a 192² ROI, and the full table was the largest single cost of
  // a tracked frame (perf, pose_speed_bench --profile 192); the sums read are the same
  // integers either way.
  void attach(const std::int32_t* pixels, int w, int h, std::ptrdiff_t stride) noexcept;
  // RT: makes columns x0..x1 and rows y0..y1 (inclusive, inside the attached region) readable
  // by add_rect. The first call tables that rectangle widened by kCoverMargin; a rectangle
  // lower down adds the missing rows; one further left, right or up tables the whole region.
  // Worst case per attach: one partial and one whole table, plus rows. Not for build()'s tables.
  void cover(int x0, int y0, int x1, int y1) noexcept;
  static constexpr int kCoverMargin = 8;

  // The tabled part: columns origin_x()..origin_x()+width()-1, rows likewise (the whole region
  // after build()).
  int origin_x() const noexcept { return ox_; }
  int origin_y() const noexcept { return oy_; }
  int width() const noexcept { return w_; }
  int height() const noexcept { return h_; }
  std::size_t row_stride() const noexcept { return static_cast<std::size_t>(w_) + 1; }
  const std::int64_t* sums() const noexcept { return sum_.data(); }
  const std::int64_t* square_sums() const noexcept { return sum_sq_.data(); }
  std::int64_t total() const noexcept { return sum_[static_cast<std::size_t>(h_) * row_stride() + w_]; }
  std::int64_t total_squares() const noexcept { return sum_sq_[static_cast<std::size_t>(h_) * row_stride() + w_]; }

  // Adds Σf and Σf² over columns x0..x1 and rows y0..y1 (inclusive, region coordinates, inside
  // the tabled part) to sum and square_sum.
  void add_rect(int x0, int y0, int x1, int y1, std::int64_t& sum, std::int64_t& square_sum) const noexcept {
    const std::size_t stride = row_stride();
    const std::size_t ya = static_cast<std::size_t>(y0 - oy_) * stride, yb = static_cast<std::size_t>(y1 + 1 - oy_) * stride;
    const std::size_t xa = static_cast<std::size_t>(x0 - ox_), xb = static_cast<std::size_t>(x1 + 1 - ox_);
    sum += sum_[yb + xb] - sum_[yb + xa] - sum_[ya + xb] + sum_[ya + xa];
    square_sum += sum_sq_[yb + xb] - sum_sq_[yb + xa] - sum_sq_[ya + xb] + sum_sq_[ya + xa];
  }

  std::size_t memory_bytes() const noexcept { return (sum_.size() + sum_sq_.size()) * sizeof(std::int64_t); }

 private:
  template <typename T>
  void build_impl(const T* pixels, int w, int h, std::ptrdiff_t stride) noexcept;
  // Tables columns x0..x1-1 of the attached region, rows y0..y1-1 (fresh); add_rows extends
  // the tabled part down to row y1-1.
  void table_part(int x0, int y0, int x1, int y1) noexcept;
  void add_rows(int y1) noexcept;

  int max_w_, max_h_;
  int ox_ = 0, oy_ = 0, w_ = 0, h_ = 0;
  // The attached region (on demand), and whether any of it is tabled yet.
  const std::int32_t* src_ = nullptr;
  int src_w_ = 0, src_h_ = 0;
  std::ptrdiff_t src_stride_ = 0;
  bool tabled_ = false;
  std::vector<std::int64_t> sum_, sum_sq_;
};

}  // namespace sempose::pose
