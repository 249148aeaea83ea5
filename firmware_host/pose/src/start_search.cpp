#include "sempose/pose/start_search.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/box_downsample.hpp"
#include "sempose/rt/angle.hpp"

namespace sempose::pose {
namespace {

// Within `radius` of a place another target holds: that object is taken.
bool held_by_another(const HeldPlaces& held, double x, double y, double radius) noexcept {
  for (int i = 0; i < held.count && i < kMaxHeldPlaces; ++i) {
    if (std::hypot(x - held.x_px[i], y - held.y_px[i]) < radius) return true;
  }
  return false;
}

}  // namespace

StartSearch::StartSearch(const config::TrackerConfig& cfg, const EngineSizes& sizes, const AngleGrid& angles,
                         FftCorrelator& coarse, FftCorrelator* coarse_wide, FftCorrelator& half, RoiLoader& loader, RoiRescaler& rescaler,
                         const ScaleProbe& probe, const ScaleEvidenceCheck& evidence, const OrientationWalk& walk,
                         AngleSweep& sweep, CorrelationMaps& maps)
    : cfg_(cfg),
      sizes_(sizes),
      angles_(angles),
      coarse_(coarse),
      coarse_wide_(coarse_wide),
      half_(half),
      loader_(loader),
      rescaler_(rescaler),
      probe_(probe),
      evidence_(evidence),
      walk_(walk),
      sweep_(sweep),
      maps_(maps),
      levels_(search_scale_levels(cfg)),
      active_(levels_),
      coarse_frame_(static_cast<std::size_t>(sizes.coarse_max_w) * sizes.coarse_max_h, 0),
      level_frame_(coarse_frame_.size(), 0),
      coarse_map_(coarse_frame_.size(), 0.0f),
      tried_(static_cast<std::size_t>(std::max(1, cfg.search_candidates))),
      candidates_(cfg.search_candidates, std::max(2, sizes.coarse_pattern_px / 2)) {}

void StartSearch::resample_coarse(int cw, int ch, double s, int max_w, int max_h, int& lw, int& lh) noexcept {
  lw = std::min(max_w, std::min(sizes_.coarse_max_w, static_cast<int>((cw - 1) / s) + 1));
  lh = std::min(max_h, std::min(sizes_.coarse_max_h, static_cast<int>((ch - 1) / s) + 1));
  const std::int32_t* in = coarse_frame_.data();
  for (int y = 0; y < lh; ++y) {
    const double v = std::min(y * s, ch - 1.0);
    const int y0 = std::min(static_cast<int>(v), ch - 2);
    const double wy = v - y0;
    const std::int32_t* r0 = in + static_cast<std::ptrdiff_t>(y0) * cw;
    const std::int32_t* r1 = r0 + cw;
    std::int32_t* o = level_frame_.data() + static_cast<std::ptrdiff_t>(y) * lw;
    for (int x = 0; x < lw; ++x) {
      const double u = std::min(x * s, cw - 1.0);
      const int x0 = std::min(static_cast<int>(u), cw - 2);
      const double wx = u - x0;
      const double top = r0[x0] + wx * (r0[x0 + 1] - r0[x0]);
      const double bot = r1[x0] + wx * (r1[x0 + 1] - r1[x0]);
      o[x] = static_cast<std::int32_t>(std::lround(top + wy * (bot - top)));
    }
  }
}

double StartSearch::load_at(const std::uint16_t* px, int w, int rx, int ry, int rw, int rh, int bits, double s) noexcept {
  const std::uint16_t* roi = px + static_cast<std::size_t>(ry) * w + rx;
  if (std::fabs(s - 1.0) <= RoiRescaler::kMinChange) return loader_.load(roi, rw, rh, w, bits) ? 1.0 : 0.0;
  const std::uint16_t* resampled = rescaler_.rescale(roi, rw, rh, w, bits, s);
  return loader_.load(resampled, rw, rh, rw, RoiRescaler::out_bits(bits)) ? s : 0.0;
}

double StartSearch::refine_factor(const PatternBank& bank, const Measurement& m, double span) const noexcept {
  const double step = ScaleProbe::kStep;
  const int n = static_cast<int>(std::ceil(span / step));
  const double window = 1.0 - (n + 1) * step;  // every score over the same pixels (ScaleProbe::score)
  double best = -3.0;
  int ib = 0;
  for (int i = -n; i <= n; ++i) {
    const double sc = probe_.score(bank, m, 1.0 + i * step, window);
    if (sc > best) {
      best = sc;
      ib = i;
    }
  }
  if (best < -1.5) return 1.0;
  const double f = 1.0 + ib * step;
  if (ib == -n || ib == n) return f;
  const double lo = probe_.score(bank, m, f - step, window), hi = probe_.score(bank, m, f + step, window);
  const double curv = lo - 2.0 * best + hi;
  if (!(curv < 0) || lo < -1.5 || hi < -1.5) return f;
  return f + std::clamp(0.5 * (lo - hi) / curv, -0.5, 0.5) * step;
}

bool StartSearch::prefer_opposite(const Measurement& m, const Measurement& f, const AnglePrior& prior) const noexcept {
  if (std::fabs(f.score - m.score) >= kFlipTieScore) return f.score > m.score;
  return prior.known && std::fabs(rt::wrap_deg(f.j * angles_.step_deg - prior.phi_deg)) < kFlipPriorDeg;
}

Measurement StartSearch::search(const PatternBank& bank, const std::uint16_t* px, int w, int h, int bits,
                                const AnglePrior& prior, const ScalePrior& scale_prior, int& roi_x, int& roi_y,
                                double& found_scale, const HeldPlaces& held) noexcept {
  Measurement none;
  const int d = sizes_.search_factor, pattern_px = sizes_.pattern_px, cp = sizes_.coarse_pattern_px;
  const int cw = std::min(w / d, sizes_.coarse_max_w), ch = std::min(h / d, sizes_.coarse_max_h);
  if (cw < cp || ch < cp) return none;
  box_downsample<std::uint16_t, std::int32_t, std::int32_t>(px, w, 0, 0, d, cw, ch, coarse_frame_.data());
  // The levels around the expected scale, inside the scales the tracker can follow.
  const double expected = std::clamp(scale_prior.scale, kTrackedScaleMin, kTrackedScaleMax);
  int n_levels = 0;
  for (std::size_t i = 0; i < (scale_prior.narrow ? 1 : levels_.size()); ++i) {
    const double s = std::clamp(expected * levels_[i], kTrackedScaleMin, kTrackedScaleMax);
    if (i > 0 && std::fabs(std::log(s / expected)) < 0.5 * std::log(kSearchLevelRatio)) continue;  // clamped onto it
    active_[static_cast<std::size_t>(n_levels++)] = s;
  }
  candidates_.clear();
  // A start area (the config's, until the target is first TRACKING), in the coarse map's
  // displacements: a candidate's centre is ux·d − coarse_offset + c_p in the frame.
  {
    const double c_p0 = (pattern_px - 1) / 2.0;
    candidates_.keep_within((held.within_x_px - c_p0 + sizes_.coarse_offset_px) / d,
                            (held.within_y_px - c_p0 + sizes_.coarse_offset_px) / d,
                            held.within_r_px > 0 ? held.within_r_px / d + 1.0 : 0.0);
  }
  for (int l = 0; l < n_levels; ++l) {
    const double s = active_[static_cast<std::size_t>(l)];
    // The level's frame (the scanned one enlarged by 1/s) on the smaller correlator that holds
    // it: a level ≥ 1 and the narrow search run at the scanned field's FFT size, not at the
    // 0.8 level's (1.56× the points at 640×480; FFTW's plan for 100×75 is slower still).
    const int want_w = std::min(sizes_.coarse_max_w, s == 1.0 ? cw : static_cast<int>((cw - 1) / s) + 1);
    const int want_h = std::min(sizes_.coarse_max_h, s == 1.0 ? ch : static_cast<int>((ch - 1) / s) + 1);
    const bool wide = coarse_wide_ != nullptr && bank.coarse_wide_spectrum(0) != nullptr &&
                      (want_w > coarse_.fft_w() || want_h > coarse_.fft_h());
    FftCorrelator& corr = wide ? *coarse_wide_ : coarse_;
    bool loaded = false;
    if (s == 1.0) {
      loaded = corr.load(coarse_frame_.data(), cw, ch, cw);
    } else {
      int lw = 0, lh = 0;
      resample_coarse(cw, ch, s, corr.fft_w(), corr.fft_h(), lw, lh);
      loaded = lw >= cp && lh >= cp && corr.load(level_frame_.data(), lw, lh, lw);
    }
    if (!loaded) continue;
    const int vw = corr.valid_w(), vh = corr.valid_h();
    // A resampled level is smoother than the scanned frame and its ZNCCs run higher: a
    // scale-1 target's place went to the 0.8 level (the real lamella scene at 2.5 e⁻/px).
    // Its scores give way by kCoarseTiePerLevel per level away from the expected scale.
    const float coarse_handicap =
        n_levels > 1 ? static_cast<float>(kCoarseTiePerLevel * std::fabs(std::log(s / expected)) /
                                          std::log(kSearchLevelRatio))
                     : 0.0f;
    for (int k = 0; k < bank.coarse_angles(); ++k) {
      corr.correlate(wide ? bank.coarse_wide_spectrum(k) : bank.coarse_spectrum(k), coarse_map_.data());
      candidates_.add_local_maxima(coarse_map_.data(), vw, vh, k, l, s, (cp - 1) / 2.0, coarse_handicap);
    }
  }
  Fine best;
  best.m.score = -2.0f;
  float best_rank = -10.0f;
  double best_cx = 0, best_cy = 0;
  int best_k = 0;
  const int rw = std::min(sizes_.roi_px, w), rh = std::min(sizes_.roi_px, h);
  const int max_moves = static_cast<int>(std::ceil(cfg_.search_refine_step_deg / angles_.step_deg)) + 2;
  const double c_p = (pattern_px - 1) / 2.0;
  // A level's candidate is at most √kSearchLevelRatio off the target's scale; a narrow search's
  // one level covers what the scale may have moved while the target was lost.
  const double span = n_levels > 1 ? std::sqrt(kSearchLevelRatio) - 1.0 + ScaleProbe::kStep : kNarrowSpan;
  int tried = 0;
  for (int c = 0; c < candidates_.size(); ++c) {
    const StartCandidate& cd = candidates_[c];
    Tried& t = tried_[static_cast<std::size_t>(tried)];
    t.cx = cd.ux * d - sizes_.coarse_offset_px + c_p;
    t.cy = cd.uy * d - sizes_.coarse_offset_px + c_p;
    if (held_by_another(held, t.cx, t.cy, pattern_px / 4.0)) continue;
    t.k = cd.k;
    t.level = cd.level;
    t.coarse_score = cd.score;
    t.fine = measure_place(bank, px, w, h, bits, prior, t.cx, t.cy, cd.k, active_[static_cast<std::size_t>(cd.level)], span,
                           n_levels > 1);
    // Rank by coarse + fine score: the ×8 level averages 64 pixels per sample and is the
    // more discriminative statistic at a few electrons per pixel; the fine level refines.
    t.rank = t.fine.m.score + cd.score;
    if (t.fine.m.valid) ++tried;
  }
  // Over several scale levels the fine scores come from differently resampled ROIs (a
  // resampled one is smoother: its ZNCC runs higher at low dose): each candidate's is taken
  // again on the scanned ROI's own pixels, the pattern stretched to its scale, over its own
  // support (the scale probe's score). Without it, a look-alike 190 px away in the real
  // lamella scene won at 6 e⁻/px.
  if (n_levels > 1) {
    for (int i = 0; i < tried; ++i) {
      Tried& t = tried_[static_cast<std::size_t>(i)];
      const double sc = t.fine.load_scale * t.fine.factor;
      // One measured in the scanned ROI has its score already (measure_place): no reload.
      if (t.fine.scanned_score < -1.5 &&
          !loader_.load(px + static_cast<std::size_t>(t.fine.ry) * w + t.fine.rx, rw, rh, w, bits))
        continue;
      // A scale away from the expected one needs a better score to win (kScaleTiePerLevel per
      // level of distance): the real scene holds look-alikes at other scales.
      const double levels_away = std::fabs(std::log(sc / expected)) / std::log(kSearchLevelRatio);
      // Every pixel: the probe's every third left the target and its 180° look-alike tied at
      // 6 e⁻/px (the procedural lamella).
      const double scanned = t.fine.scanned_score > -1.5
                                 ? t.fine.scanned_score
                                 : probe_.score(bank, in_scanned_roi(t.fine), sc, sc * (1.0 - ScaleProbe::kStep), 1);
      t.rank = static_cast<float>(scanned - kScaleTiePerLevel * levels_away) + t.coarse_score;
    }
  }
  // The runner-up at another place (more than a quarter pattern away: a look-alike), for the
  // tracker's search check.
  float runner_rank = -4.0f, best_coarse = 0.0f;
  const double far_px = pattern_px / 4.0;
  for (int i = 0; i < tried; ++i) {
    const Tried& t = tried_[static_cast<std::size_t>(i)];
    const bool apart = best.m.valid && std::hypot(t.cx - best_cx, t.cy - best_cy) > far_px;
    if (t.rank > best_rank) {
      if (apart) runner_rank = std::max(runner_rank, best_rank);
      best_rank = t.rank;
      best = t.fine;
      best_cx = t.cx;
      best_cy = t.cy;
      best_k = t.k;
      best_coarse = t.coarse_score;
    } else if (apart) {
      runner_rank = std::max(runner_rank, t.rank);
    }
  }
  if (!best.m.valid) return none;
  // The expected scale is a prior: a winner whose scale is more than kPriorBand away from it
  // is checked against the same place measured at the expected scale, both scored on the
  // scanned ROI's own pixels (the same ones for both), and kept only when the evidence is
  // clear (ScaleEvidenceCheck). A gripper whose jaws opened matches a larger rigid pattern a
  // little better (1.10–1.17) and, tracked from there, its body was dragged 3–4 px; a
  // resampled frame is smoother than the scanned one and a self-similar texture (the real
  // lamella crop) matches a stretched copy of itself a few px off.
  const double won_scale = best.load_scale * best.factor;
  if (std::fabs(std::log(won_scale / expected)) > kPriorBand) {
    // At the expected scale exactly (no refinement span): that is the hypothesis kept.
    const Fine at_prior = measure_place(bank, px, w, h, bits, prior, best_cx, best_cy, best_k, expected, 0.0, false);
    if (at_prior.m.valid && loader_.load(px + static_cast<std::size_t>(best.ry) * w + best.rx, rw, rh, w, bits)) {
      const ScaleEvidence ev = evidence_.compare(bank, in_scanned_roi(best), won_scale, in_scanned_roi(at_prior),
                                                 at_prior.load_scale * at_prior.factor);
      if (!ev.clear) best = at_prior;
    }
  }
  roi_x = best.rx;
  roi_y = best.ry;
  // The target's centre in the scanned ROI.
  const Measurement in_raw = in_scanned_roi(best);
  double x_raw = in_raw.ux + in_raw.dx + c_p, y_raw = in_raw.uy + in_raw.dy + c_p;
  found_scale = best.load_scale * best.factor;
  Measurement m = best.m;
  // Measured again at the refined scale when it moved by more than the rescaler's threshold:
  // a pose from a pattern ≥ 3 % off the target's size is biased (its angle most).
  if (std::fabs(found_scale - best.load_scale) > RoiRescaler::kMinChange) {
    const double s = load_at(px, w, best.rx, best.ry, rw, rh, bits, found_scale);
    if (s != 0.0) {
      const int ex = static_cast<int>(std::lround((rw - 1) / 2.0 + (x_raw - (rw - 1) / 2.0) / s - c_p));
      const int ey = static_cast<int>(std::lround((rh - 1) / 2.0 + (y_raw - (rh - 1) / 2.0) / s - c_p));
      half_.correlate(bank.spectrum(m.j), maps_.work());
      const SearchWindow near{ex / 2 - 2, ey / 2 - 2, ex / 2 + 3, ey / 2 + 3};
      const Peak pk = find_peak(maps_.work(), half_.valid_w(), half_.valid_h(), near);
      Measurement again = walk_.measure(bank, m.j, pk, max_moves);
      if (again.valid) {
        const ScaleReading r = probe_.read(bank, again);
        again.steps += m.steps + 1;
        m = again;
        found_scale = s * (r.valid ? r.factor : 1.0);
        x_raw = RoiRescaler::to_raw(m.ux + m.dx + c_p, rw, s);
        y_raw = RoiRescaler::to_raw(m.uy + m.dy + c_p, rh, s);
      }
    }
  }
  set_top_left(m, x_raw - c_p, y_raw - c_p);
  m.flip_score = best.m.flip_score;  // the tracker's flip check (measured at the winner's place)
  m.coarse_score = best_coarse;       // and its search check
  m.runner_up_rank = runner_rank;
  return m;
}

void StartSearch::set_top_left(Measurement& m, double x, double y) noexcept {
  m.ux = static_cast<int>(std::floor(x));
  m.uy = static_cast<int>(std::floor(y));
  m.dx = x - m.ux;
  m.dy = y - m.uy;
}

Measurement StartSearch::in_scanned_roi(const Fine& f) const noexcept {
  const double c_p = (sizes_.pattern_px - 1) / 2.0;
  Measurement m = f.m;
  set_top_left(m, RoiRescaler::to_raw(f.m.ux + f.m.dx + c_p, f.rw, f.load_scale) - c_p,
               RoiRescaler::to_raw(f.m.uy + f.m.dy + c_p, f.rh, f.load_scale) - c_p);
  return m;
}

StartSearch::Fine StartSearch::measure_place(const PatternBank& bank, const std::uint16_t* px, int w, int h, int bits,
                                             const AnglePrior& prior, double cx, double cy, int k, double level_scale,
                                             double span, bool common_score) noexcept {
  Fine out;
  const int d = sizes_.search_factor, pattern_px = sizes_.pattern_px;
  const double c_p = (pattern_px - 1) / 2.0;
  const int rw = std::min(sizes_.roi_px, w), rh = std::min(sizes_.roi_px, h);
  const int max_moves = static_cast<int>(std::ceil(cfg_.search_refine_step_deg / angles_.step_deg)) + 2;
  const int rx = std::clamp(static_cast<int>(std::lround(cx - (rw - 1) / 2.0)), 0, w - rw);
  const int ry = std::clamp(static_cast<int>(std::lround(cy - (rh - 1) / 2.0)), 0, h - rh);
  const double s = load_at(px, w, rx, ry, rw, rh, bits, level_scale);
  if (s == 0.0) return out;
  // The coarse position is good to about ±d/2 px: look for the fine peak only near it, so
  // that at low dose a chance peak elsewhere in the ROI cannot outscore the target. In a
  // ROI resampled by 1/s the target's centre is (c + (raw − c)/s).
  const int ex = static_cast<int>(std::lround((rw - 1) / 2.0 + (cx - rx - (rw - 1) / 2.0) / s - c_p));
  const int ey = static_cast<int>(std::lround((rh - 1) / 2.0 + (cy - ry - (rh - 1) / 2.0) / s - c_p));
  const SearchWindow win{(ex - d - 2) / 2, (ey - d - 2) / 2, (ex + d + 3) / 2, (ey + d + 3) / 2};  // binned px
  Measurement m = sweep_.sweep(bank, angles_.index_of(bank.coarse_angle_deg(k)), cfg_.search_refine_window_deg,
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
    if (f.valid && prefer_opposite(m, f, prior)) {
      const float other = m.score;
      m = f;
      m.flip_score = other;
    } else {
      m.steps = f.steps;
      if (f.valid) m.flip_score = f.score;
    }
  }
  out.m = m;
  out.rx = rx;
  out.ry = ry;
  out.rw = rw;
  out.rh = rh;
  out.load_scale = s;
  if (m.valid) {
    out.factor = refine_factor(bank, m, span);  // while this ROI is loaded
    // Loaded as scanned: the candidates' common score (search(), over several levels only) can
    // be taken now. An every-pixel score costs nine of the refinement's: a one-level search,
    // which never reads it, spent ~40 % of its time there (pose_speed_bench under perf).
    if (common_score && s == 1.0) out.scanned_score = probe_.score(bank, m, out.factor, out.factor * (1.0 - ScaleProbe::kStep), 1);
  }
  return out;
}

std::size_t StartSearch::memory_bytes() const noexcept {
  return coarse_map_.size() * sizeof(float) + (coarse_frame_.size() + level_frame_.size()) * sizeof(std::int32_t);
}

}  // namespace sempose::pose
