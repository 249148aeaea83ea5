// The tracker: builds the stages at setup and runs them in sequence per frame.
//   frame → (bad / re-acquire / full field?) → start search  ─┐
//                                          → ROI load → FFT peak at the predicted angle
//                                            → orientation walk + fit → recovery sweep
//                                            → refinement seam ────────┤
//   loss policy (accept / coast / lost) → motion model → temporal filter → PoseEstimate
#include "sempose/pose/tracker.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>

#include "sempose/pose/angle_grid.hpp"
#include "sempose/pose/angle_sweep.hpp"
#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/loss_policy.hpp"
#include "sempose/pose/motion_model.hpp"
#include "sempose/pose/orientation_walk.hpp"
#include "sempose/pose/pattern_bank.hpp"
#include "sempose/pose/pose_filter.hpp"
#include "sempose/pose/pose_refinement.hpp"
#include "sempose/pose/roi_loader.hpp"
#include "sempose/pose/start_search.hpp"
#include "sempose/pose/subpixel_fit.hpp"
#include "sempose/rt/angle.hpp"

namespace sempose::pose {

namespace {
// The outer ring of the pattern is made up at setup (prefilter edges replicated: 2 px per
// pass; bicubic rotation clamps its 2 px support at the square's edge): keep it out of the
// mask, or those pixels pull the peak off the true pose by a few tenths of a pixel in the
// pattern's own frame (a bias that turns with the target).
double mask_inset_px(const config::TrackerConfig& c) noexcept { return 2.0 + 2.0 * c.prefilter_passes; }
}  // namespace

struct Tracker::Impl {
  // Setup: the stages, in the order a tracked frame meets them. Members are built in
  // declaration order; later stages keep references to earlier ones.
  const config::TrackerConfig cfg;
  const EngineSizes sizes;
  const AngleGrid angles;
  const PatternMask fine_mask, half_mask, coarse_mask;
  FftCorrelator half, coarse;  // the 2×2-binned ROI level; the coarse full-field level
  ExactScorer scorer;
  RoiLoader loader;
  CorrelationMaps maps;
  const SubpixelFit fit;
  const OrientationWalk walk;
  AngleSweep sweep;
  StartSearch search;
  const PoseRefinement refinement;
  LossPolicy loss;
  MotionModel motion;
  PoseFilter filter;
  std::vector<std::unique_ptr<const PatternBank>> banks;
  std::vector<double> nm_per_px;

  bool tracking = false;
  config::ScanLimits field;  // the scan field's size (from setup, then from the frames)
  std::atomic<bool> reacquire{false};
  std::atomic<std::uint8_t> active{0};

  Impl(const config::TrackerConfig& c, const EngineSizes& s, int field_width, int field_height)
      : cfg(c),
        sizes(s),
        angles{static_cast<int>(std::lround(360.0 / c.angle_step_deg)), c.angle_step_deg},
        fine_mask(s.pattern_px, c.circular_mask, 8, mask_inset_px(c)),
        half_mask(s.pattern_px / 2, c.circular_mask, 8, mask_inset_px(c) / 2),
        coarse_mask(s.coarse_pattern_px, c.circular_mask),
        half(s.half_fft_px, s.half_fft_px, half_mask),
        coarse(good_fft_size(s.coarse_max_w), good_fft_size(s.coarse_max_h), coarse_mask),
        scorer(fine_mask, s.roi_fft_px),
        loader(c.prefilter_passes, s.roi_fft_px, scorer, half),
        maps(static_cast<std::size_t>(s.half_fft_px) * s.half_fft_px),
        fit(c.subpixel == "gaussian", c.fit_noise_correction),
        walk(scorer, fit, angles),
        sweep(half, walk, angles, maps),
        search(cfg, sizes, angles, coarse, half, loader, walk, sweep, maps),
        refinement(scorer),
        loss(cfg),
        motion(c.predict_velocity),
        filter(c.filter) {
    field.field_w = field_width;
    field.field_h = field_height;
  }

  PoseEstimate update(const PoseFrame& frame) noexcept;
  Measurement track(const PatternBank& bank) noexcept;
  void to_estimate(const Measurement& m, int origin_x, int origin_y, PoseEstimate& e) const noexcept;
  void go_lost() noexcept;
  void accept(PoseEstimate& e, const PoseFrame& frame, bool fresh) noexcept;
};

// Tracking: the predicted angle's FFT peak in the loaded ROI, the walk and the fit; when the
// walk hit its bound or the score collapsed, a bounded angle sweep in this ROI before giving
// up (a fast spin or a slip in angle is recovered here, not followed).
Measurement Tracker::Impl::track(const PatternBank& bank) noexcept {
  const int max_moves = cfg.max_angle_steps_per_frame;
  const int j_pred = angles.index_of(motion.predicted_phi_deg());
  half.correlate(bank.spectrum(j_pred), maps.work());
  maps.keep_work_as_best();
  Measurement m = walk.measure(bank, j_pred, find_peak(maps.best(), half.valid_w(), half.valid_h()), max_moves);
  m.steps += 1;
  if ((loss.weak(m) || m.unsettled) && cfg.recover_sweep_deg > 0) {
    Measurement r = sweep.sweep(bank, m.unsettled ? m.j : j_pred, cfg.recover_sweep_deg, cfg.recover_step_deg, max_moves);
    r.steps += m.steps;
    if (r.score > m.score) m = r;
    else m.steps = r.steps;
  }
  return refinement.refine(bank, m);
}

void Tracker::Impl::to_estimate(const Measurement& m, int origin_x, int origin_y, PoseEstimate& e) const noexcept {
  const int pattern_px = sizes.pattern_px;
  e.x_px = origin_x + m.ux + m.dx + (pattern_px - 1) / 2.0;
  e.y_px = origin_y + m.uy + m.dy + (pattern_px - 1) / 2.0;
  e.phi_deg = rt::wrap_deg((m.j + m.dj) * angles.step_deg);
  e.meas_x_px = e.x_px;
  e.meas_y_px = e.y_px;
  e.meas_phi_deg = e.phi_deg;
  e.score = std::clamp(m.score, -1.0f, 1.0f);
  e.psr = m.psr;
  e.angle_steps = m.steps;
}

void Tracker::Impl::go_lost() noexcept {
  filter.reset();
  tracking = false;
  loss.reset();
  motion.reset();
}

// An accepted pose: the motion model and the recent score learn it, then the reported pose
// goes through the temporal filter (a pass-through unless tracker.filter is on), timed at
// mid-scan: with a varying dwell the ROI's centre is scanned mid-frame.
void Tracker::Impl::accept(PoseEstimate& e, const PoseFrame& frame, bool fresh) noexcept {
  e.state = TrackState::kTracking;
  motion.accept(e.x_px, e.y_px, e.phi_deg, fresh);
  loss.accepted(e.score);
  tracking = true;
  if (fresh) filter.reset();
  const double t_s = 0.5e-9 * (static_cast<double>(frame.t_scan_start_ns) + static_cast<double>(frame.t_scan_end_ns));
  const PoseSample f = filter.update({t_s, e.x_px, e.y_px, e.phi_deg});
  e.x_px = f.x_px;
  e.y_px = f.y_px;
  e.phi_deg = f.phi_deg;
}

PoseEstimate Tracker::Impl::update(const PoseFrame& frame) noexcept {
  PoseEstimate e;
  const std::uint8_t set = active.load(std::memory_order_relaxed);
  e.pattern_set = set;
  e.x_px = motion.x_px();
  e.y_px = motion.y_px();
  e.phi_deg = motion.phi_deg();
  if (frame.field_w > 0 && frame.field_h > 0) {
    field.field_w = frame.field_w;
    field.field_h = frame.field_h;
  }
  const Roi& roi = frame.roi;
  const std::uint16_t* px = frame.pixels;
  if (frame.bad || px == nullptr || roi.w <= 0 || roi.h <= 0) {
    e.state = tracking ? TrackState::kLost : TrackState::kAcquiring;
    e.reason_bits = kReasonBadFrame;
    return e;
  }
  const PatternBank& bank = *banks[set];
  const bool full_field = field.is_full_field(roi.x, roi.y, roi.w, roi.h);
  if (reacquire.exchange(false, std::memory_order_relaxed)) {
    go_lost();
    if (!full_field) {
      e.state = TrackState::kAcquiring;
      e.reason_bits = kReasonCommanded;
      return e;
    }
  }

  // A full-field frame while tracking (scanned before the last search's result reached the
  // scan plan): track in its crop at the predicted pose instead of searching again.
  Roi scored = roi;
  if (full_field && tracking) {
    const Roi crop = motion.window_at_prediction(std::min(sizes.roi_px, roi.w), std::min(sizes.roi_px, roi.h), roi.w, roi.h);
    px += static_cast<std::size_t>(crop.y) * roi.w + crop.x;
    scored = {roi.x + crop.x, roi.y + crop.y, crop.w, crop.h};
  }
  if (!tracking || scored.w > sizes.roi_fft_px || scored.h > sizes.roi_fft_px) {
    int rx = 0, ry = 0;
    e.searched = true;
    const Measurement m = search.search(bank, px, roi.w, roi.h, frame.bits, motion.last_angle(), rx, ry);
    if (m.valid) to_estimate(m, roi.x + rx, roi.y + ry, e);
    if (loss.found(m)) {
      accept(e, frame, true);
    } else {
      e.state = TrackState::kAcquiring;
      e.reason_bits = m.valid ? loss.weak_reasons(m) : static_cast<std::uint8_t>(kReasonFlatFrame);
      go_lost();
    }
    return e;
  }

  // Tracking: one forward FFT for this ROI, then the walk.
  const int pattern_px = sizes.pattern_px;
  if (scored.w < pattern_px || scored.h < pattern_px || !loader.load(px, scored.w, scored.h, roi.w, frame.bits)) {
    e.state = TrackState::kLost;
    e.reason_bits = static_cast<std::uint8_t>((scored.w < pattern_px || scored.h < pattern_px) ? kReasonOutOfField
                                                                                                  : kReasonFlatFrame);
    e.score = 0;
    go_lost();
    return e;
  }
  const Measurement m = track(bank);
  to_estimate(m, scored.x, scored.y, e);
  if (m.unsettled) e.reason_bits |= kReasonAngleUnsettled;
  if (motion.prediction_outside(field.field_w, field.field_h)) e.reason_bits |= kReasonOutOfField;
  switch (loss.judge(m)) {
    case FrameVerdict::kAccept:
      accept(e, frame, false);
      break;
    case FrameVerdict::kLost:
      e.reason_bits |= loss.weak_reasons(m);
      e.state = TrackState::kLost;
      go_lost();
      break;
    case FrameVerdict::kCoast:
      // Not yet lost: report the measurement with its reasons, coast on the motion model.
      e.reason_bits |= loss.weak_reasons(m);
      e.state = TrackState::kTracking;
      motion.coast();
      break;
  }
  return e;
}

// ---------------------------------------------------------------------------------------

Tracker::Tracker(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Tracker::~Tracker() = default;

std::unique_ptr<Tracker> Tracker::create(const config::TrackerConfig& cfg, std::vector<PatternSet> sets,
                                         const config::ScanLimits& limits, rt::Status& status) {
  auto fail = [&](std::string why) {
    status = rt::Status::failure("tracker: " + std::move(why));
    return std::unique_ptr<Tracker>();
  };
  if (sets.empty()) return fail("no pattern given (need at least one pattern set)");
  const int pattern_px = sets[0].image.width;
  for (std::size_t i = 0; i < sets.size(); ++i) {
    const PatternImage& im = sets[i].image;
    const std::string which = "pattern set " + std::to_string(i) + ": ";
    if (im.empty()) return fail(which + "the pattern image is empty");
    if (im.width != im.height)
      return fail(which + "the pattern is " + std::to_string(im.width) + "x" + std::to_string(im.height) +
                  "; patterns must be square");
    if (im.pixels.size() != static_cast<std::size_t>(im.width) * im.height)
      return fail(which + "pixel count does not match width x height");
    if (im.width != pattern_px)
      return fail(which + "is " + std::to_string(im.width) + " px, pattern set 0 is " + std::to_string(pattern_px) +
                  " px; all pattern sets of a target must have the same size");
    if (!(sets[i].nm_per_px > 0)) return fail(which + "nm_per_px must be > 0");
  }
  if (sets.size() > 255) return fail("at most 255 pattern sets");
  // The settings' own rules (shared with the config reader), checked against the pattern
  // actually given rather than tracker.pattern_size_px.
  const config::SettingProblem problem = config::check_tracker_sizes(cfg, pattern_px);
  if (problem) return fail("tracker." + problem.key + ": " + problem.message);
  if (limits.field_w < pattern_px || limits.field_h < pattern_px) return fail("the scan field is smaller than the pattern");

  const EngineSizes sizes = EngineSizes::of(cfg, pattern_px, limits.field_w, limits.field_h);
  auto impl = std::make_unique<Impl>(cfg, sizes, limits.field_w, limits.field_h);
  Impl& t = *impl;
  for (std::size_t i = 0; i < sets.size(); ++i) {
    PatternBankSpec spec;
    spec.pattern = std::move(sets[i].image);
    spec.shape = std::move(sets[i].mask);
    spec.shape_margin_px = cfg.shape_mask_margin_px;
    spec.prefilter_passes = cfg.prefilter_passes;
    spec.angle_step_deg = cfg.angle_step_deg;
    spec.coarse_step_deg = cfg.search_angle_step_deg;
    spec.coarse_factor = sizes.search_factor;
    std::string why;
    auto bank = PatternBank::build(spec, {t.fine_mask, t.half_mask, t.half, t.coarse_mask, t.coarse}, why);
    if (!bank) return fail("pattern set " + std::to_string(i) + ": " + why);
    t.banks.push_back(std::move(bank));
    t.nm_per_px.push_back(sets[i].nm_per_px);
  }
  status = rt::Status::success();
  if (t.half.execute_allocates() || t.coarse.execute_allocates()) {
    status.message = "tracker: warning: no allocation-free FFTW plan found for " + std::to_string(sizes.roi_fft_px) +
                     "x" + std::to_string(sizes.roi_fft_px) + " or the coarse size; the loop may call malloc";
  }
  return std::unique_ptr<Tracker>(new Tracker(std::move(impl)));
}

Roi Tracker::next_roi() const noexcept {
  const Impl& t = *impl_;
  const int field_w = t.field.field_w, field_h = t.field.field_h;
  if (!t.tracking || t.reacquire.load(std::memory_order_relaxed)) return {0, 0, field_w, field_h};
  return t.motion.window_at_prediction(std::min(t.sizes.roi_px, field_w), std::min(t.sizes.roi_px, field_h), field_w,
                                       field_h);
}

PoseEstimate Tracker::update(const PoseFrame& frame) noexcept { return impl_->update(frame); }

bool Tracker::select_pattern_set(std::uint8_t set) noexcept {
  if (set >= impl_->banks.size()) return false;
  if (impl_->active.exchange(set, std::memory_order_relaxed) != set) {
    // A new magnification changes the target's size on screen: find it again.
    impl_->reacquire.store(true, std::memory_order_relaxed);
  }
  return true;
}

std::uint8_t Tracker::pattern_set() const noexcept { return impl_->active.load(std::memory_order_relaxed); }
double Tracker::nm_per_px() const noexcept { return impl_->nm_per_px[impl_->active.load(std::memory_order_relaxed)]; }
void Tracker::request_reacquire() noexcept { impl_->reacquire.store(true, std::memory_order_relaxed); }

std::size_t Tracker::memory_bytes() const noexcept {
  const Impl& t = *impl_;
  std::size_t b = t.half.buffer_bytes() + t.coarse.buffer_bytes();
  b += t.scorer.memory_bytes() + t.loader.memory_bytes() + t.maps.memory_bytes() + t.search.memory_bytes();
  for (const auto& bank : t.banks) b += bank->memory_bytes();
  return b;
}

}  // namespace sempose::pose
