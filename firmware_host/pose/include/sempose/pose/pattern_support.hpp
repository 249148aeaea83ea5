// The support of a pattern: which of its pixels take part in a score. The circle inscribed in
// the square pattern (or the whole square), optionally cut to the target's own shape turned
// with each angle, stored as horizontal bands (a window sum over the support costs four
// summed-area look-ups per band). Setup only, except the accessors.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sempose::pose {

struct MaskBand {
  int y0, y1;  // inclusive pattern rows
  int x0, x1;  // inclusive pattern columns
};

// The pattern's support: its inscribed circle as a stack of bands (or the full square).
// inset_px shrinks the circle's radius: the pattern's outer pixels are not trustworthy after
// setup-time filtering and rotation (edges replicated, bicubic support clamped), and a mask
// that reaches them compares made-up pixels with real ones — an offset that turns with the
// target.
class PatternMask {
 public:
  PatternMask(int size_px, bool circular, int bands_per_half = 8, double inset_px = 0);
  int size_px() const noexcept { return size_; }
  std::int64_t count() const noexcept { return count_; }
  const std::vector<MaskBand>& bands() const noexcept { return bands_; }
  bool inside(int x, int y) const noexcept { return bitmap_[static_cast<std::size_t>(y * size_ + x)] != 0; }
  const std::uint8_t* bitmap() const noexcept { return bitmap_.data(); }

 private:
  int size_;
  std::int64_t count_ = 0;
  std::vector<MaskBand> bands_;
  std::vector<std::uint8_t> bitmap_;
};

// Makes a pattern ready for correlation: zero outside the mask, zero mean and unit L2 norm
// inside. Returns false when the pattern is flat under the mask (or the mask is empty).
bool normalize_pattern(float* pattern, const PatternMask& mask) noexcept;
// The same for any support: inside[size_px²], non-zero = pattern pixel.
bool normalize_pattern(float* pattern, int size_px, const std::uint8_t* inside) noexcept;

// A support bitmap (size_px², non-zero = inside) as row runs, consecutive rows with the same
// run merged into one band: window sums over it cost four summed-area look-ups per band.
std::vector<MaskBand> bands_of(const std::uint8_t* inside, int size_px);

// Bands widened to whole chunk_px-column chunks inside the pattern, neighbouring bands with the
// same widened columns merged: the exact scorer's dot product runs over these (the pattern is
// zero outside its support, so the extra products add exactly nothing, and every chunk is one
// vector multiply-add).
std::vector<MaskBand> widen_to_chunks(const PatternMask& mask, int chunk_px);

// Grows a 0/1 mask (size_px², 1.0 = inside) by a disk of radius_px: the target's outline and
// a thin ring of what surrounds it stay in the support (a silhouette's position lives in its
// edges; the interior alone can be nearly flat).
void dilate_disk(std::vector<float>& mask, int size_px, double radius_px);

// A shape mask (size_px², 1.0 = inside) turned by phi_deg with the pattern's own resampler and
// cut to `within`: out[i] = 1 where both hold. Returns the number of pixels inside.
std::int64_t turned_support(const std::vector<float>& shape, int size_px, double phi_deg, const std::uint8_t* within,
                            std::vector<float>& scratch, std::vector<std::uint8_t>& out);

}  // namespace sempose::pose
