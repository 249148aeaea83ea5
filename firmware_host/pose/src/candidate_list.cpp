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
  // Most of a map is below the list's last score once the list is full: screened 16 pixels at
  // a time by a branch-free (vectorised) test before the per-pixel one (perf, pose_speed_bench
  // --profile-search 640 480 levels: the per-pixel scan was a fifth of a start search). The
  // screen is the per-pixel test itself, so the same candidates go in, in the same order.
  constexpr int kChunk = 16;
  const int capacity = static_cast<int>(items_.size());
  if (capacity == 0) return;
  bool full = size_ == capacity;
  float last = full ? items_[static_cast<std::size_t>(size_ - 1)].score : 0.0f;
  for (int y = 0; y < vh; ++y) {
    const float* row = map + static_cast<std::size_t>(y) * vw;
    for (int x0 = 0; x0 < vw; x0 += kChunk) {
      const int x_end = std::min(vw, x0 + kChunk);
      if (x_end - x0 == kChunk) {
        int any = 0;
#pragma omp simd reduction(| : any)
        for (int i = 0; i < kChunk; ++i) {
          const float s = row[x0 + i];
          any |= static_cast<int>(!(s <= 0.0f)) & static_cast<int>(!full || !(s - handicap <= last));
        }
        if (!any) continue;
      }
      for (int x = x0; x < x_end; ++x) {
        const float s = row[x];
        if (s <= 0.0f) continue;
        if (full && s - handicap <= last) continue;
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
        full = size_ == capacity;
        last = full ? items_[static_cast<std::size_t>(size_ - 1)].score : 0.0f;
      }
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
