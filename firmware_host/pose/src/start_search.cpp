#include "sempose/pose/start_search.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/box_downsample.hpp"
#include "sempose/rt/angle.hpp"

namespace sempose::pose {

StartSearch::StartSearch(const config::TrackerConfig& cfg, const EngineSizes& sizes, const AngleGrid& angles,
                         FftCorrelator& coarse, FftCorrelator& half, RoiLoader& loader, const OrientationWalk& walk,
                         AngleSweep& sweep, CorrelationMaps& maps)
    : cfg_(cfg),
      sizes_(sizes),
      angles_(angles),
      coarse_(coarse),
      half_(half),
      loader_(loader),
      walk_(walk),
      sweep_(sweep),
      maps_(maps),
      coarse_frame_(static_cast<std::size_t>(sizes.coarse_max_w) * sizes.coarse_max_h, 0),
      coarse_map_(coarse_frame_.size(), 0.0f),
      candidates_(cfg.search_candidates, std::max(2, sizes.coarse_pattern_px / 2)) {}

bool StartSearch::prefer_opposite(const Measurement& m, const Measurement& f, const AnglePrior& prior) const noexcept {
  if (std::fabs(f.score - m.score) >= kFlipTieScore) return f.score > m.score;
  return prior.known && std::fabs(rt::wrap_deg(f.j * angles_.step_deg - prior.phi_deg)) < kFlipPriorDeg;
}

Measurement StartSearch::search(const PatternBank& bank, const std::uint16_t* px, int w, int h, int bits,
                                const AnglePrior& prior, int& roi_x, int& roi_y) noexcept {
  Measurement none;
  const int d = sizes_.search_factor, pattern_px = sizes_.pattern_px;
  const int cw = std::min(w / d, sizes_.coarse_max_w), ch = std::min(h / d, sizes_.coarse_max_h);
  if (cw < sizes_.coarse_pattern_px || ch < sizes_.coarse_pattern_px) return none;
  box_downsample<std::uint16_t, std::int32_t, std::int32_t>(px, w, 0, 0, d, cw, ch, coarse_frame_.data());
  if (!coarse_.load(coarse_frame_.data(), cw, ch, cw)) return none;
  candidates_.clear();
  const int vw = coarse_.valid_w(), vh = coarse_.valid_h();
  for (int k = 0; k < bank.coarse_angles(); ++k) {
    coarse_.correlate(bank.coarse_spectrum(k), coarse_map_.data());
    candidates_.add_local_maxima(coarse_map_.data(), vw, vh, k);
  }
  Measurement best;
  best.score = -2.0f;
  float best_rank = -10.0f;
  const int rw = std::min(sizes_.roi_px, w), rh = std::min(sizes_.roi_px, h);
  const int max_moves = static_cast<int>(std::ceil(cfg_.search_refine_step_deg / angles_.step_deg)) + 2;
  for (int c = 0; c < candidates_.size(); ++c) {
    const StartCandidate& cd = candidates_[c];
    const double cx = cd.ux * d - sizes_.coarse_offset_px + (pattern_px - 1) / 2.0;
    const double cy = cd.uy * d - sizes_.coarse_offset_px + (pattern_px - 1) / 2.0;
    const int rx = std::clamp(static_cast<int>(std::lround(cx - (rw - 1) / 2.0)), 0, w - rw);
    const int ry = std::clamp(static_cast<int>(std::lround(cy - (rh - 1) / 2.0)), 0, h - rh);
    if (!loader_.load(px + static_cast<std::size_t>(ry) * w + rx, rw, rh, w, bits)) continue;
    // The coarse position is good to about ±d/2 px: look for the fine peak only near it, so
    // that at low dose a chance peak elsewhere in the ROI cannot outscore the target.
    const int ex = static_cast<int>(std::lround(cx - (pattern_px - 1) / 2.0)) - rx;
    const int ey = static_cast<int>(std::lround(cy - (pattern_px - 1) / 2.0)) - ry;
    const SearchWindow win{(ex - d - 2) / 2, (ey - d - 2) / 2, (ex + d + 3) / 2, (ey + d + 3) / 2};  // binned px
    Measurement m = sweep_.sweep(bank, angles_.index_of(bank.coarse_angle_deg(cd.k)), cfg_.search_refine_window_deg,
                                 cfg_.search_refine_step_deg, max_moves, win);
    // The coarse level keeps one angle per place, and elongated targets (a needle, a
    // lamella) look much alike turned by 180° at ×8 and a few electrons per pixel: try the
    // opposite angle too. Turned about the pattern's centre, the look-alike sits elsewhere
    // (twice the offset of the target's own centre from the pattern's centre, up to a
    // quarter pattern), so the opposite angle gets its own position search: one binned FFT
    // at φ+180° around the match, then the climb, the walk and the fit; the better exact
    // full-resolution score wins.
    if (m.valid) {
      const int jf = angles_.wrap(m.j + angles_.count / 2);
      half_.correlate(bank.spectrum(jf), maps_.work());
      const int reach = pattern_px / 8;  // binned px: a quarter pattern at full resolution
      const SearchWindow around{m.ux / 2 - reach, m.uy / 2 - reach, m.ux / 2 + reach, m.uy / 2 + reach};
      const Peak pk = find_peak(maps_.work(), half_.valid_w(), half_.valid_h(), around);
      Measurement f = walk_.measure(bank, jf, pk, max_moves);
      f.steps += m.steps + 1;
      if (f.valid && prefer_opposite(m, f, prior)) m = f;
      else m.steps = f.steps;
    }
    // Rank by coarse + fine score: the ×8 level averages 64 pixels per sample and is the
    // more discriminative statistic at a few electrons per pixel; the fine level refines.
    if (m.valid && m.score + cd.score > best_rank) {
      best_rank = m.score + cd.score;
      best = m;
      roi_x = rx;
      roi_y = ry;
    }
  }
  return best;
}

std::size_t StartSearch::memory_bytes() const noexcept {
  return coarse_map_.size() * sizeof(float) + coarse_frame_.size() * sizeof(std::int32_t);
}

}  // namespace sempose::pose
