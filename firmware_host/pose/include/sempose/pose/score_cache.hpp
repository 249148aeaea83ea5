// One measurement's exact scores, remembered: the climb, the walk and the fit revisit the
// same (angle, displacement) many times. A fixed ring of 64 entries (no allocation); the
// count of scores actually computed is part of the frame's reported effort.
#pragma once

#include <algorithm>
#include <array>

#include "sempose/pose/angle_grid.hpp"
#include "sempose/pose/exact_scorer.hpp"

namespace sempose::pose {

struct CachedScore {
  int j = 0, x = 0, y = 0;
  ScoreParts parts;
  float score = -2.0f;  // -2: the window leaves the ROI
};

class ScoreCache {
 public:
  ScoreCache(const ExactScorer& scorer, const PatternBank& bank, const AngleGrid& angles) noexcept
      : scorer_(scorer), bank_(bank), angles_(angles) {}

  const PatternBank& bank() const noexcept { return bank_; }
  const ExactScorer& scorer() const noexcept { return scorer_; }

  CachedScore evaluate(int j, int x, int y) noexcept {
    j = angles_.wrap(j);
    for (int i = 0; i < size_; ++i) {
      const CachedScore& c = entries_[static_cast<std::size_t>(i)];
      if (c.j == j && c.x == x && c.y == y) return c;
    }
    CachedScore v;
    v.j = j;
    v.x = x;
    v.y = y;
    v.parts = scorer_.parts(bank_, j, x, y);
    v.score = v.parts.inside ? ExactScorer::zncc(v.parts) : -2.0f;
    ++computed_;
    entries_[static_cast<std::size_t>(next_)] = v;
    next_ = (next_ + 1) % static_cast<int>(entries_.size());
    size_ = std::max(size_, next_ == 0 ? static_cast<int>(entries_.size()) : next_);
    return v;
  }
  float score(int j, int x, int y) noexcept { return evaluate(j, x, y).score; }
  int computed() const noexcept { return computed_; }

 private:
  const ExactScorer& scorer_;
  const PatternBank& bank_;
  const AngleGrid& angles_;
  std::array<CachedScore, 64> entries_{};
  int size_ = 0, next_ = 0, computed_ = 0;
};

}  // namespace sempose::pose
