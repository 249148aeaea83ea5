// Learned appearance, the non-RT half: from the observer's batches (AppearanceStats), which
// pixels of the pattern the target explains. Per pattern set it keeps the running sums of
// every accepted batch and decides per block_px² block of the pattern's frame: a block whose
// mean squared residual against the recorded pattern exceeds outlier_ratio × what detector
// noise and the pose's jitter explain (noise variance + (jitter² + (angle jitter · r)²) · |∇t|²) is not the target
// (background under the rim that changes as the target moves, a moving jaw) and leaves the
// support. The support stays inside the user's shape mask (a prior) and the pattern circle.
// Drift check (Matthews, Ishikawa & Baker 2004): a new support is kept only if the mean of
// the aligned observations over it still is the recorded pattern — ZNCC >= min_consistency
// at its best integer shift, that shift's sub-pixel peak within max_drift_px of zero — and
// it keeps min_support_fraction of the circle. A rejected batch is not added to the sums, so
// frames tracked at a wrong pose cannot teach the model. Not RT (allocates at construction).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sempose/config/appearance_config.hpp"
#include "sempose/pose/appearance_observer.hpp"

namespace sempose::pose {

struct AppearanceDecision {
  bool accepted = false;
  std::string why;                    // the rejection's reason
  std::vector<std::uint8_t> support;  // size_px², 1 = the target's pixel (when accepted)
  double support_fraction = 0;        // of the circle
  double consistency = 0;             // ZNCC of the mean observation with the recorded pattern
  double drift_px = 0;                // sub-pixel offset of that match
  int frames = 0;                     // frames in the running sums, this batch included
};

class AppearanceModel {
 public:
  // circle: the pattern's support bitmap (size_px²); references[k] / priors[k]: pattern set
  // k's recorded pattern, prefiltered (size_px²), and its shape prior (size_px², 1.0 = may be
  // the target; empty = the whole circle).
  AppearanceModel(const config::AppearanceConfig& cfg, int size_px, const std::uint8_t* circle,
                  std::vector<std::vector<float>> references, std::vector<std::vector<float>> priors);

  // One batch of the observer's: the support it gives with the sums so far, checked.
  AppearanceDecision update(const AppearanceStats& batch);
  // The support the running sums of set k give (no check, no change): for tests and figures.
  std::vector<std::uint8_t> support_of(const AppearanceStats& sums, std::uint8_t set) const;
  // The drift check of a support against set k's recorded pattern (fills consistency, drift_px).
  bool consistent(const AppearanceStats& sums, const std::vector<std::uint8_t>& support, std::uint8_t set,
                  AppearanceDecision& d) const;
  const AppearanceStats& sums(std::uint8_t set) const { return sums_[set]; }

 private:
  config::AppearanceConfig cfg_;
  int n_;
  std::vector<std::uint8_t> circle_;
  std::int64_t circle_count_ = 0;
  std::vector<std::vector<float>> refs_;
  std::vector<std::vector<float>> grad2_;  // |∇t|² of each reference
  std::vector<std::vector<float>> priors_;  // 1.0 = may be the target; empty = the circle
  std::vector<AppearanceStats> sums_;
};

}  // namespace sempose::pose
