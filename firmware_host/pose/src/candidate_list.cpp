#include "sempose/pose/candidate_list.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <utility>

namespace sempose::pose {

CandidateList::CandidateList(int capacity, int separation_px)
    : items_(static_cast<std::size_t>(capacity)), separation_px_(separation_px) {}

void CandidateList::add_local_maxima(const float* map, int vw, int vh, int k, int level, double scale,
                                     double centre_px, float handicap) noexcept {
  const int capacity = static_cast<int>(items_.size());
  for (int y = 0; y < vh; ++y) {
    for (int x = 0; x < vw; ++x) {
      const float s = map[static_cast<std::size_t>(y) * vw + x];
      if (s <= 0.0f) continue;
      if (size_ == capacity && s - handicap <= items_[static_cast<std::size_t>(size_ - 1)].score) continue;
      bool local_max = true;
      for (int j = -1; j <= 1 && local_max; ++j) {
        for (int i = -1; i <= 1; ++i) {
          const int xx = x + i, yy = y + j;
          if ((i || j) && xx >= 0 && yy >= 0 && xx < vw && yy < vh && map[static_cast<std::size_t>(yy) * vw + xx] > s) {
            local_max = false;
            break;
          }
        }
      }
      if (!local_max) continue;
      insert({static_cast<int>(std::lround((x + centre_px) * scale - centre_px)),
              static_cast<int>(std::lround((y + centre_px) * scale - centre_px)), k, s - handicap, level});
    }
  }
}

void CandidateList::insert(const StartCandidate& c) noexcept {
  if (area_r_ > 0 && std::hypot(c.ux - area_ux_, c.uy - area_uy_) > area_r_) return;
  const int sep = separation_px_;
  for (int i = 0; i < size_; ++i) {
    StartCandidate& have = items_[static_cast<std::size_t>(i)];
    if (std::abs(have.ux - c.ux) < sep && std::abs(have.uy - c.uy) < sep) {
      if (have.score >= c.score) return;
      have = c;
      std::sort(items_.begin(), items_.begin() + size_,
                [](const StartCandidate& a, const StartCandidate& b) { return a.score > b.score; });
      return;
    }
  }
  if (size_ < static_cast<int>(items_.size())) {
    items_[static_cast<std::size_t>(size_++)] = c;
  } else {
    items_[static_cast<std::size_t>(size_ - 1)] = c;
  }
  for (int i = size_ - 1; i > 0 && items_[static_cast<std::size_t>(i)].score > items_[static_cast<std::size_t>(i - 1)].score; --i)
    std::swap(items_[static_cast<std::size_t>(i)], items_[static_cast<std::size_t>(i - 1)]);
}

}  // namespace sempose::pose
