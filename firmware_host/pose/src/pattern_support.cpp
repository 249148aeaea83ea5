#include "sempose/pose/pattern_support.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/bicubic_rotate.hpp"

namespace sempose::pose {

PatternMask::PatternMask(int size_px, bool circular, int bands_per_half, double inset_px)
    : size_(size_px), bitmap_(static_cast<std::size_t>(size_px) * size_px, 0) {
  if (!circular) {
    bands_.push_back({0, size_ - 1, 0, size_ - 1});
  } else {
    // Rows are grouped by their distance from the centre; a band takes the narrowest
    // half-width of its rows so every mask pixel lies inside the circle (rotated
    // patterns have real data there) while each window sum costs only 4 look-ups per band.
    const double c = (size_ - 1) / 2.0;
    const double radius = std::max(1.0, size_ / 2.0 - inset_px);
    const int band_rows = std::max(1, (size_ / 2 + bands_per_half - 1) / bands_per_half);
    auto half_width = [&](int row) {
      const double dy = std::fabs(row - c) + 0.5;
      return std::sqrt(std::max(0.0, radius * radius - dy * dy));
    };
    int row = 0;
    while (row < size_) {
      const bool upper = row < c;
      const int key = static_cast<int>(std::fabs(row - c) / band_rows);
      int end = row;
      while (end + 1 < size_ && ((end + 1) < c) == upper &&
             static_cast<int>(std::fabs(end + 1 - c) / band_rows) == key) {
        ++end;
      }
      double hw = 1e9;
      for (int r = row; r <= end; ++r) hw = std::min(hw, half_width(r));
      const int x0 = static_cast<int>(std::ceil(c + 0.5 - hw - 1e-9));
      const int x1 = static_cast<int>(std::floor(c - 0.5 + hw + 1e-9));
      if (x0 <= x1) bands_.push_back({row, end, x0, x1});
      row = end + 1;
    }
  }
  for (const auto& b : bands_) {
    for (int y = b.y0; y <= b.y1; ++y) {
      for (int x = b.x0; x <= b.x1; ++x) bitmap_[static_cast<std::size_t>(y * size_ + x)] = 1;
    }
    count_ += static_cast<std::int64_t>(b.y1 - b.y0 + 1) * (b.x1 - b.x0 + 1);
  }
}

bool normalize_pattern(float* p, const PatternMask& mask) noexcept {
  return normalize_pattern(p, mask.size_px(), mask.bitmap());
}

bool normalize_pattern(float* p, int n, const std::uint8_t* inside) noexcept {
  double sum = 0;
  std::int64_t count = 0;
  for (int i = 0; i < n * n; ++i) {
    if (inside[i]) {
      sum += p[i];
      ++count;
    }
  }
  if (count == 0) return false;
  const double mean = sum / static_cast<double>(count);
  double ss = 0;
  for (int i = 0; i < n * n; ++i) {
    float& v = p[i];
    v = inside[i] ? static_cast<float>(v - mean) : 0.0f;
    ss += static_cast<double>(v) * v;
  }
  if (!(ss > 1e-12 * static_cast<double>(count))) return false;
  const float scale = static_cast<float>(1.0 / std::sqrt(ss));
  for (int i = 0; i < n * n; ++i) p[i] *= scale;
  return true;
}

std::vector<MaskBand> bands_of(const std::uint8_t* inside, int n) {
  std::vector<MaskBand> out;
  std::size_t prev_begin = 0, prev_end = 0;  // the previous row's bands in out
  for (int y = 0; y < n; ++y) {
    const std::size_t row_begin = out.size();
    for (int x = 0; x < n;) {
      if (!inside[y * n + x]) {
        ++x;
        continue;
      }
      int x1 = x;
      while (x1 + 1 < n && inside[y * n + x1 + 1]) ++x1;
      bool merged = false;
      for (std::size_t k = prev_begin; k < prev_end && !merged; ++k) {
        if (out[k].x0 == x && out[k].x1 == x1 && out[k].y1 == y - 1) {
          out[k].y1 = y;
          merged = true;
        }
      }
      if (!merged) out.push_back({y, y, x, x1});
      x = x1 + 1;
    }
    // Bands extended into this row stay candidates for the next one.
    prev_begin = std::min(prev_begin, row_begin);
    prev_end = out.size();
    std::size_t first_live = prev_end;
    for (std::size_t k = prev_begin; k < prev_end; ++k)
      if (out[k].y1 == y) first_live = std::min(first_live, k);
    prev_begin = first_live;
  }
  return out;
}

std::vector<MaskBand> widen_to_chunks(const PatternMask& mask, int chunk_px) {
  std::vector<MaskBand> out;
  const int size = mask.size_px();
  for (MaskBand b : mask.bands()) {
    b.x0 = b.x0 / chunk_px * chunk_px;
    b.x1 = std::min(size - 1, (b.x1 / chunk_px + 1) * chunk_px - 1);
    if (!out.empty() && out.back().x0 == b.x0 && out.back().x1 == b.x1 && out.back().y1 + 1 == b.y0) {
      out.back().y1 = b.y1;
    } else {
      out.push_back(b);
    }
  }
  return out;
}

void dilate_disk(std::vector<float>& mask, int n, double r) {
  if (r <= 0) return;
  const int ri = static_cast<int>(std::floor(r));
  const std::vector<float> src = mask;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      if (src[static_cast<std::size_t>(y) * n + x] != 0.0f) continue;
      bool hit = false;
      for (int dy = -ri; dy <= ri && !hit; ++dy)
        for (int dx = -ri; dx <= ri && !hit; ++dx) {
          const int xx = x + dx, yy = y + dy;
          hit = dx * dx + dy * dy <= r * r && xx >= 0 && yy >= 0 && xx < n && yy < n &&
                src[static_cast<std::size_t>(yy) * n + xx] != 0.0f;
        }
      if (hit) mask[static_cast<std::size_t>(y) * n + x] = 1.0f;
    }
}

std::int64_t turned_support(const std::vector<float>& shape, int n, double phi_deg, const std::uint8_t* within,
                            std::vector<float>& scratch, std::vector<std::uint8_t>& out) {
  rotate_pattern(shape.data(), n, phi_deg, scratch.data());
  std::int64_t count = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = within[i] && scratch[i] >= 0.5f;
    count += out[i];
  }
  return count;
}

}  // namespace sempose::pose
