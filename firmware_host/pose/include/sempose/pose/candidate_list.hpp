// The start search's best places: the strongest positive local maxima of the coarse ZNCC maps
// (one map per coarse angle), at most `capacity`, sorted by score, no two closer than
// `separation_px` in both x and y (the better one keeps the place). Setup allocates; the rest
// is RT.
#pragma once

#include <vector>

namespace sempose::pose {

struct StartCandidate {
  int ux = 0, uy = 0;  // displacement in the (unscaled) coarse map
  int k = 0;           // coarse angle index
  float score = 0;
  int level = 0;       // the start search's scale level
};

class CandidateList {
 public:
  CandidateList(int capacity, int separation_px);

  void clear() noexcept { size_ = 0; }
  // RT: keep only places within r of (ux, uy) in the coarse map (r ≤ 0: anywhere), e.g. a start
  // area told in the config: a twin outside it must not take the list's places.
  void keep_within(double ux, double uy, double r) noexcept {
    area_ux_ = ux, area_uy_ = uy, area_r_ = r;
  }
  int size() const noexcept { return size_; }
  const StartCandidate& operator[](int i) const noexcept { return items_[static_cast<std::size_t>(i)]; }

  // RT: every positive local maximum (3×3) of a map_w×map_h map at coarse angle k. A map of
  // the coarse frame resampled by 1/scale (scale level `level`) has its places mapped back to
  // the unscaled coarse frame (pattern centre (centre_px, centre_px) from the top-left kept), so
  // that one target seen at two levels is one place.
  // A candidate's score is the map's minus `handicap` (a level whose scores run high).
  void add_local_maxima(const float* map, int map_w, int map_h, int k, int level = 0, double scale = 1.0,
                        double centre_px = 0.0, float handicap = 0.0f) noexcept;
  // RT: one candidate (replaces a weaker one at the same place, or the weakest when full).
  void insert(const StartCandidate& c) noexcept;

 private:
  std::vector<StartCandidate> items_;
  int size_ = 0;
  int separation_px_;
  double area_ux_ = 0, area_uy_ = 0, area_r_ = 0;
};

}  // namespace sempose::pose
