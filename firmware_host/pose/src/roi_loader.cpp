#include "sempose/pose/roi_loader.hpp"

#include <algorithm>

#include "sempose/pose/box_downsample.hpp"

namespace sempose::pose {

RoiLoader::RoiLoader(int prefilter_passes, int max_roi_px, ExactScorer& scorer, FftCorrelator& half)
    : max_roi_px_(max_roi_px),
      prefilter_(prefilter_passes, max_roi_px, max_roi_px),
      scorer_(scorer),
      half_(half),
      filtered_(static_cast<std::size_t>(max_roi_px) * max_roi_px, 0),
      binned_(static_cast<std::size_t>(half.fft_w()) * half.fft_h(), 0) {}

bool RoiLoader::load(const std::uint16_t* px, int w, int h, std::ptrdiff_t stride, int bits) noexcept {
  w = std::min(w, max_roi_px_);
  h = std::min(h, max_roi_px_);
  prefilter_.apply(px, w, h, stride, bits, filtered_.data());
  scorer_.load(filtered_.data(), w, h);
  const int bw = w / 2, bh = h / 2;
  box_downsample<std::int32_t, std::int32_t, std::int32_t>(filtered_.data(), w, 0, 0, 2, bw, bh, binned_.data());
  for (int i = 0; i < bw * bh; ++i) binned_[static_cast<std::size_t>(i)] >>= 2;
  return half_.load(binned_.data(), bw, bh, bw);
}

std::size_t RoiLoader::memory_bytes() const noexcept {
  return (filtered_.size() + binned_.size()) * sizeof(std::int32_t) + static_cast<std::size_t>(max_roi_px_) * max_roi_px_ * 16;
}

}  // namespace sempose::pose
