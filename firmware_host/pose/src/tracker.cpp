// The tracker's per-frame sequence of stages (setup is tracker_create.cpp, learned-bank swaps
// tracker_appearance.cpp, the shared state tracker_impl.hpp).
//   frame → (bad / re-acquire / full field?) → start search  ─┐
//                                          → ROI (resampled by 1/scale) load → FFT peak at the
//                                            predicted angle → orientation walk + fit
//                                            → recovery sweep → refinement seam → scale probe ─┤
//   explained check → loss policy (accept / coast / lost) → motion model, scale
//   → temporal filter → PoseEstimate
#include "sempose/pose/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "sempose/pose/attainable_score.hpp"
#include "tracker_impl.hpp"

namespace sempose::pose {

namespace {
// (1 − r²)/(1 − a²): the variance a fit with gain and offset leaves (share 1 − r² of the
// window's) over what the noise model predicts it leaves (1 − a², a the attainable score).
// The floor keeps a noise-free window finite.
float normalised_chi2(double score, double attainable) noexcept {
  const double left = 1.0 - std::clamp(score, 0.0, 1.0) * std::clamp(score, 0.0, 1.0);
  const double noise = 1.0 - attainable * attainable;
  return static_cast<float>(left / std::max(noise, 1e-4));
}

// The score a frame scanned at dwell to_ns would give where one at from_ns gave `score`:
// ZNCC's r² = S / (S + N) with the shot noise's variance N ∝ 1 / dwell (the model the carried
// pose noise uses, MotionModel::carried_noise_factor). On the default simulated needle
// standing still, 0.807 at 500 ns predicts 0.695 at 250 ns and 0.888 at 1000 ns (measured
// means 0.689 and 0.885). Unknown dwells (0) leave the score as it is.
double score_at_dwell(double score, double from_ns, double to_ns) noexcept {
  if (!(from_ns > 0) || !(to_ns > 0) || from_ns == to_ns || !(score > 0)) return score;
  const double r2 = std::clamp(score * score, 1e-4, 1.0 - 1e-9);
  const double noise_over_signal = (1.0 - r2) / r2 * from_ns / to_ns;
  return 1.0 / std::sqrt(1.0 + noise_over_signal);
}
}  // namespace

// The ZNCC the target itself would reach in the window at (cx, cy) of a frame, given the
// frame's noise as the detector delivers it (correlated along the line): attainable_score.hpp.
double Tracker::Impl::attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy, int j) const noexcept {
  if (masked_bank && j >= 0 && j < masked_bank->angles())
    return attainable_factor * pose::attainable_score(px, w, h, cx, cy, sizes.pattern_px, masked_bank->support_bands(j),
                                                      masked_bank->support_band_count(j), prefilter_noise)
                                   .score;
  return attainable_factor * pose::attainable_score(px, w, h, cx, cy, sizes.pattern_px, prefilter_noise).score;
}

void Tracker::Impl::forget_everything() noexcept {
  go_lost();
  lost_after_hold = away_from_held = lost_on_tear = false;
  tear_level = 0;
  anchor.forget();
  flip_open = false;
  search_n = 0;
  searches_rejected = 0;
  loss.forget_target();
  fit_level.forget();
  explained_level.forget();
  refind_level = 0;
  refind_research = false;
  blur_level.forget();
  scale_sigma_level.forget();
  scale = expected_scale.load(std::memory_order_relaxed);
  scale_reference = scale;
  motion = MotionModel(cfg.predict_velocity, cfg.predict_rate_poses);  // also the last angle a search's tie-break uses
}

// Tracking: the predicted angle's FFT peak in the loaded ROI, the walk and the fit; when the
// walk hit its bound or the score collapsed, a bounded angle sweep in this ROI before giving
// up (a fast spin or a slip in angle is recovered here, not followed).
Measurement Tracker::Impl::track(const PatternBank& bank, bool& swept, std::uint8_t set, const RawRoi& raw) noexcept {
  const int max_moves = cfg.max_angle_steps_per_frame;
  const int j_pred = angles.index_of(motion.predicted_phi_deg());
  half.correlate(bank.spectrum(j_pred), maps.work());
  maps.keep_work_as_best();
  Measurement m = walk.measure(bank, j_pred, find_peak(maps.best(), half.valid_w(), half.valid_h()), max_moves);
  m.steps += 1;
  swept = (loss.weak(m) || m.unsettled) && cfg.recover_sweep_deg > 0;
  if (swept) {
    Measurement r = sweep.sweep(bank, m.unsettled ? m.j : j_pred, cfg.recover_sweep_deg, cfg.recover_step_deg, max_moves);
    r.steps += m.steps;
    if (r.score > m.score) m = r;
    else m.steps = r.steps;
  }
  return refinement.refine(set, bank, m, raw);
}

// The motion check (a pose stream must never lie): a pose that lands farther from the
// prediction than the motion seen so far makes plausible is first searched again around the
// prediction — the walk may have started from a stale angle (the first frame after a search
// knows no angular rate, and a full-field scan lasts ~8 ROI frames) and climbed a
// neighbouring local maximum — and the better of the two is kept. A pose that is still
// surprising and whose score does not vouch for it (below the target's recent level by more
// than its spread) is implausible: not TRACKING. A real jump or a bounce scores at the
// target's level and passes; a look-alike or a wrong angle does not.
template <class Place>
void Tracker::Impl::check_motion(const PatternBank& bank, Measurement& m, PoseEstimate& e, bool swept, double e_origin_x,
                                 double e_origin_y, double e_scale, const Place& place) noexcept {
  const bool surprising = motion.surprising(e.x_px, e.y_px, e.phi_deg);
  // Also searched again when the pose lands where predicted but scores below the target's
  // recent level by more than the detector's noise explains (significance_z() SDs of a
  // difference of two scores, flip_sd), once the motion is known: the walk starts at the
  // predicted angle, so a walk that stopped on a local maximum short of the target is never
  // surprising, and the running spread confirmed() allows is the target's own swing, not noise.
  //  * The procedural lamella spinning at 6 e-/px passes its recorded orientation, where the
  //    bank's unrotated pattern (no interpolation) scores ~0.09 above its rotated neighbours
  //    (0.81 against 0.72): the walk stayed on that bump at 2-3 deg while the target turned on
  //    (4 -> 9 -> 12 deg behind, 0.75 -> 0.69 -> 0.62; the swing made 0.62 "confirmed"), each
  //    frame's velocity learnt from the lagging poses; the sweep found it at 11 deg, 0.714
  //    against the walk's 0.688.
  // (Not caught by it: the same lamella under charging + defocus at 2.5 e-/px, a walk stopped
  // 3.3 px off at 0.535 where the level was ~0.58 — within the noise there, 0.075 at that level.)
  const double level = loss.recent_level();
  const bool below_level =
      motion.motion_known() && level > 0 && m.score < level - significance_z() * flip_sd(level);
  // A surprising pose at the target's level is measured against the prediction too: a second
  // object of the same pattern scores at that level wherever it is (jump_declined below).
  const bool jump_at_level = surprising && motion.motion_known() && loss.confirmed(m.score);
  if ((!surprising || loss.confirmed(m.score)) && !below_level && !jump_at_level) return;
  surprised = true;
  if (!swept && cfg.recover_sweep_deg > 0) {
    const int j_pred = angles.index_of(motion.predicted_phi_deg());
    // Only positions the motion makes plausible: the sweep over the whole ROI found a
    // look-alike 20-65 px off on the needle's body (pipeline_test) that scored at the
    // target's level. The predicted pose's displacement in the binned map (the ROI is
    // centred on the prediction unless clamped at the field's edge).
    const double plausible_px = motion.has_velocity()
                                    ? std::max(MotionModel::kSurpriseFloorPx,
                                               MotionModel::kSurpriseSigmas * motion.innovation_rms_px())
                                    : 0.25 * (sizes.roi_px - sizes.pattern_px);
    const double c = (sizes.pattern_px - 1) / 2.0;
    const double ux = (motion.predicted_x_px() - e_origin_x) / e_scale - c;
    const double uy = (motion.predicted_y_px() - e_origin_y) / e_scale - c;
    const double r_b = plausible_px / e_scale / 2.0 + 1.0;
    SearchWindow win;
    win.x0 = std::max(0, static_cast<int>(std::floor(ux / 2.0 - r_b)));
    win.y0 = std::max(0, static_cast<int>(std::floor(uy / 2.0 - r_b)));
    win.x1 = std::max(win.x0 + 1, static_cast<int>(std::ceil(ux / 2.0 + r_b)) + 1);
    win.y1 = std::max(win.y0 + 1, static_cast<int>(std::ceil(uy / 2.0 + r_b)) + 1);
    Measurement r = sweep.sweep(bank, j_pred, cfg.recover_sweep_deg, cfg.recover_step_deg, cfg.max_angle_steps_per_frame, win);
    r.steps += m.steps;
    rival_within_noise = rival_within_noise || rivals(m, r, e_scale);
    if (r.score > m.score || (surprising && declines_jump(m, r, ux, uy, plausible_px, e_scale))) {
      jump_declined = jump_declined || r.score <= m.score;
      m = r;
      place(m, e);
    } else {
      m.steps = r.steps;
      e.angle_steps = m.steps;
    }
  }
  // Implausible only against a motion seen: on the first frame after a search (no velocity)
  // the floors are all there is, and declaring the frame LOST there meant a full-field search
  // after every search whose first ROI scored a little below the search's own score
  // (pipeline_test: 60 searches in 10,000 frames, some landing on look-alikes along the
  // needle's body). The sweep above still runs there: it is what finds a fast spin.
  // And only a grave surprise (6 SD of the innovations, at least 3 px / 6°): at 4 SD the
  // needle in pipeline_test, whose frame interval the governor varies, was declared
  // implausible once at its true pose and searched again.
  m.implausible = motion.motion_known() && motion.surprising(e.x_px, e.y_px, e.phi_deg, kImplausibleWider) &&
                  !loss.confirmed(m.score);
}

// Two hypotheses of one frame (measurements in the same loaded ROI, loaded at used_scale) more
// than the false-pose rule's 3 px / 10 deg apart whose scores differ by less than the noise of
// a difference of two independent scores (significance_z() × flip_sd): the frame cannot tell
// which one is the target.
bool Tracker::Impl::rivals(const Measurement& a, const Measurement& b, double used_scale) const noexcept {
  if (!(cfg.max_false_probability > 0) || !a.valid || !b.valid) return false;
  const double apart_px = used_scale * std::hypot(a.ux + a.dx - b.ux - b.dx, a.uy + a.dy - b.uy - b.dy);
  // Modulo the pattern's declared order: its looks 360°/order apart are one hypothesis.
  const double apart_deg = std::fabs(std::remainder((a.j + a.dj - b.j - b.dj) * angles.step_deg, 360.0 / angle_order));
  if (apart_px <= LossPolicy::kFalsePx && apart_deg <= LossPolicy::kFalseDeg) return false;
  const float kept = std::max(a.score, b.score), other = std::min(a.score, b.score);
  return static_cast<double>(kept) - other < significance_z() * flip_sd(kept);
}

// A surprising pose m, and r, the best hypothesis where the motion puts the target (the sweep's
// window about the prediction, ux / uy its pattern top-left in the loaded ROI): the jump is
// declined when r is a hypothesis of its own (more than the false-pose rule's kFalsePx from m,
// and still within the window after the walk: not the shoulder of m's peak) scoring at the
// target's level (LossPolicy::confirmed). The frame then holds two objects at the target's
// level, and only the motion tells which is the target: a second object of the same pattern
// beside it (pose_envelope_probe twin_crosses_down_at_45deg: the lamella on post's pose jumped
// 35 px onto the twin crossing its path at 0.80, its own place scoring at its level, and followed
// the twin, TRACKING up to 282 px off). A real jump leaves its old place empty, so its pose is
// taken as before. The motion's hypothesis is kept, UNCERTAIN (the frame favoured the other).
bool Tracker::Impl::declines_jump(const Measurement& m, const Measurement& r, double ux, double uy, double plausible_px,
                                  double used_scale) const noexcept {
  if (!(cfg.max_false_probability > 0) || !m.valid || !r.valid || !loss.confirmed(r.score)) return false;
  const double apart_px = used_scale * std::hypot(m.ux + m.dx - r.ux - r.dx, m.uy + m.dy - r.uy - r.dy);
  const double from_prediction_px = used_scale * std::hypot(r.ux + r.dx - ux, r.uy + r.dy - uy);
  return apart_px > LossPolicy::kFalsePx && from_prediction_px <= plausible_px + 2.0 * used_scale;
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
  e.refine_status = m.refine_status;
}

// σ in the loaded ROI's pixels, back to the scanned ones (a resampled ROI is 1/scale of them).
void Tracker::Impl::set_sigma(const PoseSigma& s, double used_scale, PoseEstimate& e) noexcept {
  if (!s.valid) return;
  e.sigma_x_px = s.x_px * used_scale;
  e.sigma_y_px = s.y_px * used_scale;
  e.sigma_phi_deg = s.phi_deg;
  e.sigma_scale = s.scale * used_scale;
}

// A frame blurrier than the target's frames (defocus) flattens the fit: the least-squares
// curvature is Σ ∂T·∂f / gain, not the copy's Σ (∂T)² that σ's bread is, while the noise's pull
// on the pose, Σ ∂T·n, is not blurred — so the pose's error grows by the curvature's ratio (and
// the clutter around the target smeared into the support moves it further). The score and χ²
// stay at the target's level: no fit level sees it. PoseSigma::sharpness is that ratio against
// the copy; against the target's own level (blur_level: a copy holding noise or detail the
// target's frames do not reads below 1 on every frame) it is the factor σ is too small by.
// pose_envelope_probe --case defocus_ (3 and 5 px PSF stepped in at 25 % of the run, 18 rows at
// 20 / 6 / 2.5 e-/px): the sharpness reads 0.54-0.85 of the copy's on the sharp frames,
// 0.13-0.54 on the blurred ones; the blurred frames' RMS(error/σ) 1.15-3.21 (0.59-0.99 on the
// sharp frames), 0.58-1.77 with σ × level / sharpness on every blurred frame (the level: the sharp
// frames' median). Widened only when the frame is blurrier
// than the level by more than the level's spread allows (significance_z() SDs of a frame's log,
// at least the detector noise's share, sharpness_sd), then by the whole ratio: a sharp frame
// keeps its σ. Or when the run of frames since the last loss is (the exponentially weighted mean
// of the log, kBlurRunGain, against the same spread narrowed by the mean's variance share): focus
// changes slowly against the frame rate, and at 2.5 e-/px one frame's reading scatters by ~20 %,
// which let a blurred frame through alone (the procedural lamella's first frame at 3 px, 3.9 px
// off) and let blurred frames into the level (which then crept up with the blur). Not while
// calibrating (the noise trials have no target).
void Tracker::Impl::widen_for_blur(const PoseSigma& s, PoseEstimate& e) noexcept {
  blur_widened = false;
  frame_blur = 0;
  if (!s.valid || !(s.sharpness_sd > 0)) return;
  // A frame whose cross term is within noise of 0 says only that it is no sharper than its noise.
  const double sharpness = std::max(s.sharpness, s.sharpness_sd);
  frame_blur = 1.0 / sharpness;
  const double floor_sd = s.sharpness_sd / sharpness;
  // The run's blur: the mean of the log over the frames since the last loss, exponentially
  // weighted (kBlurRunGain); its variance share of one frame's, blur_run_var.
  if (!blur_run_known) {
    blur_run = std::log(frame_blur);
    blur_run_var = 1.0;
    blur_run_known = true;
  } else {
    blur_run += kBlurRunGain * (std::log(frame_blur) - blur_run);
    blur_run_var = (1.0 - kBlurRunGain) * (1.0 - kBlurRunGain) * blur_run_var + kBlurRunGain * kBlurRunGain;
  }
  if (loss.calibrating() || !blur_level.known()) return;
  const double z = significance_z(), level = blur_level.chi2();
  double f = 1.0;
  if (blur_level.excess_sds(frame_blur, floor_sd) > z) f = frame_blur / level;
  if (blur_level.excess_sds(std::exp(blur_run), floor_sd) > z * std::sqrt(blur_run_var)) f = std::max(f, std::exp(blur_run) / level);
  if (!(f > 1.0)) return;
  e.sigma_x_px *= f;
  e.sigma_y_px *= f;
  e.sigma_phi_deg *= f;
  e.sigma_scale *= f;
  blur_widened = true;
}

// σ with every pose (issue 13 item 5), a search frame's too: it was reported as 0 ("not
// measured"), so a pose re-acquired after a loss, TRACKING on its search frame, came with no
// uncertainty at all, and above the explained check's bound it was trusted on σ = 0. The ROI
// the next frame would scan (the ROI size, centred on the pose, inside the field) is cut from
// the field, loaded at the scale found (resampled by 1/scale as an ROI frame is) and σ taken at
// the search's pose and angle, as for an ROI frame. It misses what a field scan adds: the
// target moving during the ~80 ms scan. Setup sized every buffer this uses; ~60 µs, on a
// search frame only. Returns the search's measurement placed in that loaded ROI (for the split
// check, torn()).
Tracker::Impl::FieldCut Tracker::Impl::load_field_cut(const std::uint16_t* px, const Roi& field_roi, int bits, double fx,
                                                      double fy, double load_scale) noexcept {
  FieldCut cut;
  cut.w = std::min({sizes.roi_px, sizes.roi_fft_px, field_roi.w});
  cut.h = std::min({sizes.roi_px, sizes.roi_fft_px, field_roi.h});
  if (cut.w < sizes.pattern_px || cut.h < sizes.pattern_px) return cut;
  cut.x0 = std::clamp(static_cast<int>(std::lround(fx - (cut.w - 1) / 2.0)), 0, field_roi.w - cut.w);
  cut.y0 = std::clamp(static_cast<int>(std::lround(fy - (cut.h - 1) / 2.0)), 0, field_roi.h - cut.h);
  const std::uint16_t* at = px + static_cast<std::size_t>(cut.y0) * field_roi.w + cut.x0;
  const bool rescaled = std::fabs(load_scale - 1.0) > kRescaleFrom;
  cut.used_scale = rescaled ? load_scale : 1.0;
  const std::uint16_t* load_px = at;
  std::ptrdiff_t load_stride = field_roi.w;
  int load_bits = bits;
  if (rescaled) {
    load_px = rescaler.rescale(at, cut.w, cut.h, field_roi.w, bits, cut.used_scale);
    load_stride = cut.w;
    load_bits = RoiRescaler::out_bits(bits);
  }
  cut.valid = loader.load(load_px, cut.w, cut.h, load_stride, load_bits);
  ++load_seq;
  return cut;
}

Tracker::Impl::Loaded Tracker::Impl::search_sigma(const PatternBank& bank, const Measurement& m, const std::uint16_t* px,
                                                  const Roi& field_roi, int bits, PoseEstimate& e) noexcept {
  if (!m.valid) return {};
  const double fx = e.x_px + lag_shift_px - field_roi.x, fy = e.y_px - field_roi.y;  // the pose in this frame's pixels
  const FieldCut cut = load_field_cut(px, field_roi, bits, fx, fy, e.scale);
  if (!cut.valid) return {};
  const double used_scale = cut.used_scale;
  // The pattern's top-left in the loaded ROI.
  const double c = (sizes.pattern_px - 1) / 2.0;
  const double lx = cut.loaded_x(fx) - c, ly = cut.loaded_y(fy) - c;
  Measurement at = m;
  at.ux = static_cast<int>(std::floor(lx));
  at.uy = static_cast<int>(std::floor(ly));
  at.dx = lx - at.ux;
  at.dy = ly - at.uy;
  const PoseSigma sigma = uncertainty.estimate(bank, at, e.scale / used_scale);
  set_sigma(sigma, used_scale, e);
  widen_for_blur(sigma, e);
  return {true, at, used_scale};
}

// The pose is trusted when its error SD — the larger of its own σ (the fit's covariance) and
// the pose noise the accepted poses show frame to frame (the motion model's innovations with
// the target's acceleration taken out) — makes a pose beyond the false-pose rule unlikely
// enough (LossPolicy::trusted). Its own σ misses a pose that jumped to a neighbouring maximum
// (at 1 e-/px: σ 0.5 px at poses 4-8 px off); the stream's noise sees those jumps.
//
// The stream's noise only below the explained check's upper bound (0.7): a pose the pattern
// explains that well is judged by its own σ. The innovations cannot tell pose noise from the
// target's acceleration (replay_matches_run: a 40 px sine of 3 s at 0.2 s per tracked frame,
// 7 px/frame², scores 0.8-0.9, read as ~2 px of "noise"; third differences, which cancel a
// constant acceleration, still read 1.6 px there and caught fewer wanderings at 1 e-/px), and
// the poses that wander to a neighbouring maximum score low (1 e-/px: 0.37-0.62).
//
// Below that bound the stream's noise is required, not only used when known: on a search frame
// (σ not measured) and the three ROI frames after it (the noise is known from the third
// innovation of predictions made from ROI poses) a pose's own σ is all there is, and it does
// not see a neighbouring maximum. At 1 e-/px 10 of the 14 false poses of all dose-1 rows were
// there (the warped crop's re-searches landing on a maximum 9-12 px off, kept by the walk at
// the target's score with σ 0.9 px; a search 4 px off on the needle tip); now UNCERTAIN.
//
// After a loss of the same target the stream's noise from before the loss stands in until the
// new stream shows its own (MotionModel::pose_noise_carried; a REACQUIRE or another pattern set
// forgets it), adapted to this frame (MotionModel::carried_noise_factor): a re-acquired pose the noise model
// supports is TRACKING on its first frame again, one it does not stays UNCERTAIN.
//
// With a prediction made from two ROI poses, the pose is judged by its error given where it
// landed against that prediction (MotionModel::error_given_innovation: the prediction and the
// measurement fused as a Kalman update would; LossPolicy::false_probability_offset): a pose that
// jumped to a neighbouring maximum 3-5 px off lands 4-6 px from the prediction, and its error
// given that is centred 1 px or more away from 0. At 1 e-/px those first frames of a wander
// were the last false poses (lamella on post, fast: 4.2 and 3.3 px off at the target's score,
// σ 0.4-0.6 px, the stream's noise 0.9 px: 0.4 % by σ alone, 3-6 % given the innovation).
// Not on a frame whose σ was widened for blur (widen_for_blur): the fusion takes the
// prediction's error as independent of the pose's, but the poses it was made from were as
// blurred and their errors run together (the needle tip at 20 e-/px under a 5 px PSF: 1.3-1.9 px
// off on every frame), so a pose landing near it is not vouched for. Such a pose must pass on
// its own σ too (the procedural lamella at 6 e-/px, 5 px: 3.8 px off with σ 1.04 px, TRACKING
// given its 1 px innovation).
bool Tracker::Impl::trusted_pose(const PoseEstimate& e, const Innovation& innov) const noexcept {
  double s_px = std::max(e.sigma_x_px, e.sigma_y_px), s_deg = e.sigma_phi_deg;
  // No σ (0: the fit's curvature was singular, PoseUncertainty not valid) is no vouching: a
  // pattern that is one straight edge leaves the place along the edge unknown, and its poses,
  // 20 px off, were TRACKING on σ 0 as "no error expected" (found probing: replay and run).
  if (cfg.max_false_probability > 0 && !loss.calibrating() && !(e.sigma_x_px > 0 && e.sigma_y_px > 0 && e.sigma_phi_deg > 0))
    return false;
  if (e.score < loss.explained_bound() && !motion.pose_noise_known() && !loss.calibrating()) return false;
  if (motion.pose_noise_known() && e.score < loss.explained_bound()) {
    const double k = motion.pose_noise_carried() ? motion.carried_noise_factor(frame_dwell_ns, e.score) : 1.0;
    s_px = std::max(s_px, k * motion.pose_noise_px());
    s_deg = std::max(s_deg, k * motion.pose_noise_deg());
    if (innov.known) {
      const MotionModel::ErrorGivenInnovation g = motion.error_given_innovation(innov.d_px, innov.d_deg, s_px, s_deg);
      // A blurred pose's error is shared by the poses the prediction was made from (above).
      if (blur_widened && !loss.trusted(s_px, s_deg)) return false;
      return loss.trusted_offset(g.offset_px, g.sd_px, g.offset_deg, g.sd_deg);
    }
  }
  return loss.trusted(s_px, s_deg);
}

// Before the stream's own pose noise is known (a first start: the search frame and the three
// ROI frames after it; not after a loss of the same target, whose noise is carried) a pose
// scoring at or above the explained bound is judged by its own σ alone, and σ (the fit's
// curvature) cannot see a pose held in place by a part of the pattern that did not move with the
// target. heldout_end_to_end's pattern recorded over a hole lattice: the search frame scored
// 0.86-0.90 at the recording spot, the first ROI frame 0.71-0.72 still there while the needle
// had moved 11 px on, TRACKING on σ 0.36-0.40 px: its score had fallen by 0.6-1.0 of the
// room a ZNCC of that level has, 1 - s². A score that is not confirmed (below the level since
// the search by more than max(3 SD of the scores, 0.1 of that room): the motion check's test of
// whether a score vouches for a pose) and lies below it by more than the detector's noise
// explains (significance_z() SDs of a difference of two scores, flip_sd: the below-level
// test the motion check makes once the motion is known) says the pattern no longer explains
// the frame as it did: UNCERTAIN (followed, so the stream's noise is learnt as before). On
// the `--quick` rows the first three ROI frames of a first start fell by at most 0.085 of it.
// A new target's first pose (a first start: no pose noise learnt, none carried from a stream
// before a loss) is a single field scan that nothing has confirmed: its σ is not measured, the
// target moves during the ~80 ms field scan (on `--quick` the 89 first search frames are up to
// 2.7 px off, the worst poses of their streams), and a pattern recorded over static clutter
// scores best where the clutter was, not where the target is (heldout_end_to_end's hole
// lattice: frame 0 3.3-3.7 px off at 0.84-0.90, TRACKING, the rows' only false poses). No score,
// χ² or σ on it tells those from a true one (the bench's true 0.58 px search frame has χ² 3.9),
// so it is reported UNCERTAIN, as a new SELECT's search frame already is (reason 32), and the
// next ROI frame, judged by every rule, confirms it or not. A re-acquisition after a loss of the
// same target (noise carried) is judged as before: recovery after a jump stays one frame.
bool Tracker::Impl::first_pose_unconfirmed() const noexcept {
  return cfg.max_false_probability > 0 && !loss.calibrating() && !motion.pose_noise_known();
}

bool Tracker::Impl::fell_below_search_level(float score) const noexcept {
  if (!(cfg.max_false_probability > 0) || loss.calibrating() || motion.pose_noise_known()) return false;
  const double level = loss.recent_level();
  return level > 0 && !loss.confirmed(score) && score < level - significance_z() * flip_sd(level);
}

// A score below a level the stream kept (scanned at level_dwell_ns, taken to this frame's dwell)
// by more than the confirmed margin's share of its room and the noise of a score difference.
bool Tracker::Impl::scored_below(double score, double level, double level_dwell_ns) const noexcept {
  const double l = score_at_dwell(level, level_dwell_ns, frame_dwell_ns);
  return score < l - std::max(LossPolicy::kConfirmShare * (1.0 - l * l), significance_z() * flip_sd(l));
}

// Parts of the window that move differently (the tiles of split_consistency.hpp off one affine
// field: significant at max_false_probability and at least kTilesApartPx): the pattern's static
// background holds the pose while the target moves on (hostile round 13: a needle tip over
// textured real background moving 1 px a frame, TRACKING 5-16 px behind it at 20-2.5 e-/px), or
// a gripper's jaws open. The tiles see it only while the parts are within the linear step's
// reach (~2-8 px): beyond it the target's tiles no longer fit and the background's agree again.
// So the doubt stays open while the score stays below the level before it (scored_below): the
// stream's fit is not back to what it was. A loss or a new search forgets it.
bool Tracker::Impl::parts_doubted(const Measurement& m, const PatternBank& bank, double used_scale,
                                  const PoseEstimate& e) noexcept {
  if (!(cfg.max_false_probability > 0) || loss.calibrating() || !last_known) {
    parts_doubt = false;
    parts_before = {};
    return false;
  }
  // A target turning while its ROI is scanned bends across the rows (each row sees it turned a
  // little further), which no affine field holds: the probe's spins of 15-45° a frame lost 6-32
  // points of TRACKING to this check. Judged only while the stream turns less than kTilesTurnDeg
  // a frame.
  const bool turning = motion.has_velocity() &&
                       std::fabs(rt::wrap_deg(motion.predicted_phi_deg() - motion.phi_deg())) >= kTilesTurnDeg;
  if (parts_doubt) {
    parts_doubt = scored_below(e.score, parts_level, parts_dwell_ns);
  } else if (m.valid && !turning && parts_disagree(m, bank, used_scale) && parts_before.known) {
    parts_doubt = true;
    parts_level = parts_before.score;
    parts_dwell_ns = parts_before.dwell_ns;
  }
  // The level a doubt opened on the next frame is judged against: this frame's, unless doubted.
  if (!parts_doubt) parts_before = {true, e.score, frame_dwell_ns};
  return parts_doubt;
}

// Static clutter recorded with the target (README Known limitations, look-alike background): a
// pattern that is mostly background standing still at the recording spot holds the pose there
// when the target moves away. The pose then does not move, so its innovations and the stream's
// pose noise are ~0 and σ (the fit's curvature on the clutter) is small; only the score says so:
// it falls at once from the level the target gave (0.94-0.96 at 20 e-/px) to what the clutter
// alone explains (0.70-0.74; the normalised χ² ~8× the noise's). A target that moved takes the
// pose with it (the same pattern over weaker clutter: 0.97 -> 0.79 with the pose 10 px on, on the
// needle); a target that stands still does not lose score at once but over many frames
// (charging, defocus: far less than the noise per frame). So: a score below the last accepted
// one by more than the confirmed margin's share of the room a ZNCC of that level has
// (0.1 × (1 − level²)) and the detector noise of a difference of two scores (significance_z() ×
// flip_sd) while the pose
// stood still (moved less than significance_z() × √2 × its σ, in position and angle) opens a
// doubt: its poses are followed but UNCERTAIN while the pose keeps standing still and the score
// stays below the level before the fall by that margin. It ends when the score is back or the
// pose moves (what it follows moves: not static clutter); a loss or a new search forgets it.
// Not the running SD of the accepted scores that the confirmed margin also allows: the falls
// themselves make it (0.94 / 0.71 alternating: 3 SD ~0.3 after one fall), which closed the
// doubt on the second frame.
bool Tracker::Impl::fell_while_still(const PoseEstimate& e) noexcept {
  if (!(cfg.max_false_probability > 0) || loss.calibrating() || !last_known) {
    still_doubt = false;
    return false;
  }
  const double z = significance_z();
  const double s_px = std::max(e.sigma_x_px, e.sigma_y_px), s_deg = e.sigma_phi_deg;
  const bool still = s_px > 0 && s_deg > 0 && std::hypot(e.x_px - last_x, e.y_px - last_y) <= z * std::sqrt(2.0) * s_px &&
                     std::fabs(rt::wrap_deg(e.phi_deg - last_phi)) <= z * std::sqrt(2.0) * s_deg;
  if (!still) {
    still_doubt = false;
    return false;
  }
  // Each level as this frame's dwell would score it: the governor shortens the dwell of a target
  // it tracks well, and a needle standing still at 500 ns (0.81) scores 0.69 at 250 ns. Compared
  // as scored, that fall opened the doubt on the governor's first shorter frame and the score
  // never came back: `sempose run` on the default needle standing still was TRACKING on 1 pose
  // of 3033 (the pipeline's own TrackingStep test found it).
  const auto below = [&](double level, double level_dwell_ns) { return scored_below(e.score, level, level_dwell_ns); };
  if (still_doubt) {
    still_doubt = below(still_level, still_dwell_ns);
  } else if (below(last_score, last_dwell_ns)) {
    still_doubt = true;
    still_level = last_score;
    still_dwell_ns = last_dwell_ns;
  }
  return still_doubt;
}

Tracker::Impl::SplitAllowance Tracker::Impl::split_allowance(const PoseFrame& frame, const PoseEstimate& e, int roi_h,
                                                            double used_scale) const noexcept {
  // How far the target's own motion puts the split check's parts apart per row between them
  // (torn()): its velocity per frame times the share of the frame period one row's scan
  // takes (without timestamps, one of the ROI's rows), plus the tracked scale against the
  // scale the ROI was loaded at (rows below the centre show a larger target lower). The
  // velocity is the motion model's; without one (the first ROI frame after a search) this
  // pose's move from the last one over the time since it, and the smaller of the two until
  // the motion since the search is known (the first velocity spans the long field scan).
  // Loaded-ROI px per loaded row: a rescaled ROI's rows and pixels are both 1/used_scale of
  // the scanned ones.
  const double row_share = frame_period_s > 0 && frame.t_scan_end_ns > frame.t_scan_start_ns
                               ? 1e-9 * static_cast<double>(frame.t_scan_end_ns - frame.t_scan_start_ns) / roi_h / frame_period_s
                               : 1.0 / roi_h;
  // A torn frame's followed pose teaches the motion model a false velocity (the pose jumps
  // with the part it sits on), which would excuse the torn frames after it: the speed is at
  // most the one the last TRACKING frame left (until a search).
  const double this_move_px = std::hypot(e.x_px - motion.x_px(), e.y_px - motion.y_px());
  const double velocity_px = std::hypot(motion.predicted_x_px() - motion.x_px(), motion.predicted_y_px() - motion.y_px());
  double moved_px = !motion.has_velocity()   ? this_move_px
                    : motion.motion_known() ? velocity_px
                                            : std::min(velocity_px, this_move_px);
  if (tracking_speed_px >= 0) moved_px = std::min(moved_px, tracking_speed_px);
  // A still target's move from two noisy poses reads up to ~1 px a frame at 6 e-/px
  // (kStillPx, the check's old gate): that much is noise, not motion during the scan.
  SplitAllowance a;
  a.shear_per_row = std::max(0.0, moved_px - kStillPx) * row_share;
  a.scale_per_row = std::fabs(scale / used_scale - 1.0);
  // And only while the tracked scale is steady (its running rate, ~2 frames' memory, at most
  // kStillScale of it and its last step at most kStillScaleStep), as before: a target whose
  // size changes during the scan (a scale ramp, a gripper's jaws moving, which the scale
  // readings follow) pulls the parts apart in its own way, which the motion's allowance does
  // not hold (without this gate 24 jaws and 10 scale-ramp frames of `--quick` turned
  // UNCERTAIN). Learnt from the frames the check did not find torn: a torn frame's scale
  // reading is torn too (0.97 where the target is at 1.00) and closed the gate on the torn
  // frames after it.
  a.steady_scale = std::fabs(scale_rate) <= kStillScale * scale && std::fabs(scale_step) <= kStillScaleStep * scale;
  return a;
}

// A torn frame (issue 13 item 6): the target jumped while its ROI was scanned, or a scan glitch
// moved part of the frame, so the lines scanned before show it at one place and those after at
// another, and the pose sits with one part or between them. Its score can stay at the level of
// the frames before, so neither the score rules nor fell_while_still see it (the clutter control
// rows of `pose_accuracy_bench --clutter`, frame 39: TRACKING 7-8.6 px off at 0.76-0.86; a scan
// glitch shifting the ROI's lower half by 12 px on a moving target, pose_envelope_probe
// half_shifted: 7-9 poses a row 4-12 px off). The split check (split_consistency.hpp) fits the
// rows scanned first and those scanned last apart at the pose; parts whose displacements differ
// significantly (χ², 2 dof, at max_false_probability shared over the cuts) and by at least
// kTornApartPx say the target was not rigid during the scan. Both: at 20 e-/px a whole frame of
// the needle over clutter it moved away from has parts 0.3-0.6 px apart at 4-5 SD (the clutter
// pulls each part by its own share), the torn frames 1.3 px (the linear step reads an 8 px tear
// short) at 5.7-6.5 SD. A moving target shears the parts apart by itself (the rows scanned
// later show it farther on): the check used to run only on a target the stream said stood still
// (without that gate it turned 175 `--quick` frames UNCERTAIN, most on the fast, scale ramp and
// spin rows), which let every torn frame of a moving target through. Now it runs on every pose
// otherwise TRACKING, and the shear the target's motion and its tracked scale explain
// (shear_per_row + scale_per_row, px per row between the parts' centroid rows: the caller's) is
// an allowance on top of kTornApartPx. An
// allowance, not a correction: the linear step reads a smooth shear short too (the needle tip at
// ~4 px a frame: 0.5-0.7 px apart where its velocity predicts 1.0). A turn during a raster scan
// bends the parts rather than pulling them apart (rows above and below the centre shift alike).
// On a search frame (no motion known) the allowance is 0. One pass over the footprint, RT.
//
// Along the scan lines the scale's share of the allowance does not apply. A torn frame's scale
// reading is torn too (the needle tip at 6 e-/px, the 12 px glitch: the tracked scale 0.99 →
// 0.97 over frames 42-46), and the scale's term (the tracked scale against the loaded one: 0.014
// px a row, 0.65 px over the parts' 48 rows) excused frame 46, parts 1.9 px apart; its reading
// then taught the scale's rate, which closed the steady-scale gate on 47-49: 3 ROI frames 9-10 px
// off TRACKING, parts 1.7-1.9 px apart in x at 5-5.6 SD. A change of size pulls the parts apart
// along the slow axis (rows below the centre show the target lower), not along the lines, so
// the x component alone, significant at the same χ² (2 dof) bound and beyond kTornApartPx plus
// the motion's shear only, is torn too: frame 46 is caught and the gate stays open on 47-49. The
// gate stays on both (without it on the x component the `gripper` jaws at 20 e-/px kept 11 of 60
// frames TRACKING where GripperJawsDoNotDragATrackedPose needed 12, and a 3 px hum wave lost 36
// of 960 probe frames, 23 with it). A tear along y, which the scale reading takes for a change
// of size, is kept from the tracked scale by the hold at the scale's update.
bool Tracker::Impl::torn(const Measurement& m, const PatternBank& bank, double used_scale, double shear_per_row,
                         double scale_per_row, bool* together) const noexcept {
  if (together) *together = false;  // not known until measured
  if (!(cfg.max_false_probability > 0) || loss.calibrating()) return false;
  const SplitConsistency s = split_at(bank, m);
  if (!s.valid) return false;
  if (together) *together = s.z < kTogetherZ && s.line_z < kTogetherZ;
  // The parts' distance is a 2-D Mahalanobis one, the largest of kCuts: significant when its
  // square exceeds the χ² (2 dof) quantile of max_false_probability shared over the cuts.
  const double p = std::clamp(cfg.max_false_probability / SplitConsistencyCheck::kCuts, 1e-12, 0.5);
  const double bound_sq = -2.0 * std::log(p);
  const bool apart = s.z * s.z >= bound_sq &&
                     used_scale * (s.apart_px - (shear_per_row + scale_per_row) * std::fabs(s.rows_apart)) >= kTornApartPx;
  const bool apart_along_lines = s.line_z * s.line_z >= bound_sq &&
                                 used_scale * (s.line_apart_px - shear_per_row * std::fabs(s.line_rows_apart)) >= kTornApartPx;
  return apart || apart_along_lines;
}

// The split check's measurement at the pose, once per loaded ROI (torn() and parts_disagree() both ask).
SplitConsistency Tracker::Impl::split_at(const PatternBank& bank, const Measurement& m) const noexcept {
  if (split_cache.seq != load_seq || split_cache.bank != &bank || split_cache.j != m.j || split_cache.ux != m.ux ||
      split_cache.uy != m.uy)
    split_cache = {load_seq, &bank, m.j, m.ux, m.uy, split.measure(bank, m.j, m.ux, m.uy)};
  return split_cache.s;
}

bool Tracker::Impl::parts_disagree(const Measurement& m, const PatternBank& bank, double used_scale) const noexcept {
  if (!(cfg.max_false_probability > 0) || loss.calibrating()) return false;
  const SplitConsistency s = split_at(bank, m);
  if (!s.tiles_valid || s.tiles_dof < 2) return false;
  const double z = upper_normal_quantile(cfg.max_false_probability);
  const double k = s.tiles_dof, h = 2.0 / (9.0 * k);
  const double bound = k * std::pow(1.0 - h + z * std::sqrt(h), 3);
  return s.tiles_chi2 > bound && used_scale * s.tiles_apart_px >= kTilesApartPx;
}

// A target leaving the field across an edge or a corner (pose_envelope_probe --case leave_): the
// pattern's window cannot be placed beyond the field, so the search's and the walk's maximum sits
// where the window touches the edge, however far the target went on (the needle tip re-found by
// the search at the edge 4-12 px off, TRACKING; the lamella on post's search there took its 180°
// look-alike, which the visible half matched better, and kept it: open_flip_check). A maximum on
// the boundary of the places measured is no maximum: not TRACKING. The window's half-size at the
// scale the frame was loaded at; the margin one scale reading's step more (the search reports the
// scale its probe refined, up to ScaleProbe::kStep from the level it loaded at).
bool Tracker::Impl::at_field_edge(const PoseEstimate& e, double load_scale) const noexcept {
  if (!(cfg.max_false_probability > 0) || loss.calibrating()) return false;
  const double r = 0.5 * (sizes.pattern_px - 1) * load_scale;  // the window's half-size in the field
  const double margin = 1.0 + r * ScaleProbe::kStep;
  return e.meas_x_px - r < margin || e.meas_y_px - r < margin || e.meas_x_px + r > field.field_w - 1 - margin ||
         e.meas_y_px + r > field.field_h - 1 - margin;
}

// z with 0.5·erfc(z/√2) = p, p clamped to [1e-12, 0.5].
double Tracker::Impl::upper_normal_quantile(double p_in) noexcept {
  const double p = std::clamp(p_in, 1e-12, 0.5);
  double lo = 0, hi = 10;  // 0.5·erfc(z/√2) = p, decreasing in z
  for (int i = 0; i < 50; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
  }
  return hi;
}

// Student's t quantile from the normal one z for nu degrees of freedom (Cornish–Fisher
// expansion; within 2 % of the table for nu ≥ 3, the only ones used).
double Tracker::Impl::student_t(double z, int nu) noexcept {
  const double n = std::max(1, nu), z3 = z * z * z, z5 = z3 * z * z;
  return z + (z3 + z) / (4 * n) + (5 * z5 + 16 * z3 + 3 * z) / (96 * n * n) +
         (3 * z5 * z * z + 19 * z5 + 17 * z3 - 15 * z) / (384 * n * n * n);
}

// After a search: the chosen hypothesis must lead the one 180° away by more than the score
// noise allows (significance_z SDs of one difference), else the check stays open. A trusted
// angle prior (the last tracked angle: a target does not turn 180° while lost) already chose,
// unless the check was still open when the target was lost, or the winner is turned from it:
// the search keeps to the prior only within StartSearch::kFlipTieScore, which one score
// difference's noise passes at 1 e⁻/px (the lamella on its post coming back into the field
// after leaving it by a corner: re-found 16 px and 178° off, 0.50 against the target's level
// of 0.52, followed, and TRACKING on 3 frames: pose_envelope_probe leave_corner_whole).
// A search frame whose pattern window reaches the field's edge (at_field_edge) decides nothing: the hypothesis that would fit only
// beyond the edge could not be measured, so the visible part's better match wins there (the
// lamella on post half out of the field: its 180° look-alike 14-18 px off was taken and kept for
// ~100 frames after the target came back). The check opens and the frames after it decide.
// With a shape mask the search's lead is a masked score's only, which can prefer the wrong
// hypothesis (settle_flip): the check is always opened and decided on ROI frames.
void Tracker::Impl::open_flip_check(const Measurement& m, bool prior_chose, bool censored) noexcept {
  const bool was_open = flip_open;
  flip_open = false;
  if (!(cfg.max_false_probability > 0) || (m.flip_score < -1.0f && !censored) || (prior_chose && !was_open && !censored)) return;
  const double d = m.flip_score < -1.0f ? 0.0 : static_cast<double>(m.score) - m.flip_score;
  if (!shape_masked && d >= significance_z() * flip_sd(m.score) && !censored) return;
  flip_open = true;
  flip_lead = FlipLead{};
  flip_circle = FlipLead{};
  if (!shape_masked) flip_lead.add(d);
}

// The mean difference of a flip check's scores against Student's t with n − 1 degrees of
// freedom on the differences' own spread: > 0 significant for the kept hypothesis, < 0 for the
// opposite one, 0 not yet.
int Tracker::Impl::FlipLead::verdict(double z_normal) const noexcept {
  if (n < 4) return 0;  // a spread needs a few differences (t below is good from 3 dof)
  const double mean = sum / n;
  const double spread = std::sqrt(std::max(0.0, (sum2 - n * mean * mean) / (n - 1)));
  const double sd = std::max(spread, 1e-6) / std::sqrt(static_cast<double>(n));
  const double z = student_t(z_normal, n - 1);
  return mean >= z * sd ? 1 : mean <= -z * sd ? -1 : 0;
}

bool Tracker::Impl::search_settled(const Measurement& m, const PoseEstimate& e) noexcept {
  if (!(cfg.max_false_probability > 0) || m.runner_up_rank < -3.0f) {
    search_n = 0;
    search_episode = 0;
    return true;
  }
  // The same place: within a quarter pattern and 20° of the last unsettled search's result
  // (the target moves while the field is scanned); elsewhere the evidence starts anew.
  const double moved = search_episode > 0 ? std::hypot(e.x_px - search_x, e.y_px - search_y) : 1e300;
  const bool same = search_n > 0 && moved <= sizes.pattern_px / 4.0 && std::fabs(rt::wrap_deg(e.phi_deg - search_phi)) <= 20.0;
  if (!same) search_n = 0, search_sum = 0;
  // The winner's run at one place for the majority below: any angle (a spinning target keeps
  // its place, not its angle) and half a pattern (a target moving while slow searches follow
  // one another, e.g. the PREEMPT_RT VM test's emulated CPU, ~0.5 s a search).
  search_place_n = moved <= sizes.pattern_px / 2.0 ? search_place_n + 1 : 1;
  // The lead in the search's own rank (exact + coarse score); its SD from both levels'
  // sampling noise, two candidates at different places being independent.
  search_sum += static_cast<double>(m.score) + m.coarse_score - m.runner_up_rank;
  ++search_n;
  ++search_episode;
  search_x = e.x_px;
  search_y = e.y_px;
  search_phi = e.phi_deg;
  const double c2 = std::min(1.0, static_cast<double>(m.coarse_score) * m.coarse_score);
  const double sd_coarse = (1.0 - c2) / std::sqrt(std::max(1.0, static_cast<double>(coarse_mask.count())));
  const double sd = std::hypot(flip_sd(m.score), std::sqrt(2.0) * sd_coarse);
  const bool significant = search_sum >= significance_z() * sd * std::sqrt(static_cast<double>(search_n));
  // Significant is not enough where the field is full of look-alikes (a lattice the pattern
  // was recorded over, a patch of it moving over the rest): there a static spot leads the
  // others by the same small amount search after search, and sampling noise alone let such a
  // lead pass once two searches in a row happened to agree on it (heldout_end_to_end's lattice
  // rows: 89 false TRACKING poses). So the place must also have won most of the searches since
  // the target was last settled: in a lattice each search's winner is somewhere else. (A
  // margin on the lead, as a share of the score's room, was tried and dropped: the warped
  // crop's real look-alike leads by only 0.09 of it, and the VM test's gripper never settled.)
  const bool majority = 2 * search_place_n > search_episode;
  if (significant && majority) {
    search_n = 0;
    search_episode = 0;
    return true;
  }
  return false;
}

Measurement Tracker::Impl::opposite_of(const PatternBank& bank, const Measurement& m, PoseEstimate& e) noexcept {
  const int jf = angles.wrap(m.j + angles.count / 2);
  half.correlate(bank.spectrum(jf), maps.work());
  const int reach = sizes.pattern_px / 8;  // binned px: a quarter pattern, as the search
  const SearchWindow around{m.ux / 2 - reach, m.uy / 2 - reach, m.ux / 2 + reach, m.uy / 2 + reach};
  Measurement f = walk.measure(bank, jf, find_peak(maps.work(), half.valid_w(), half.valid_h(), around),
                               cfg.max_angle_steps_per_frame);
  e.angle_steps += f.steps + 1;
  return f;
}

// A pose that jumped (the motion check was surprised) may be the target's turned look-alike: a
// target turned 180° between two frames (or a walk that slipped onto it) shows a partly
// symmetric pattern's own turned copy beside the true place, and the walk from the predicted
// angle lands there (the lamella on its post turned 180° at 2.5 e-/px: the walk's pose 15-17 px
// and 180° off at 0.66-0.69, the target's level 0.72; the motion model learnt the jump and the
// pose was TRACKING on 14 frames; the true hypothesis scored 0.705-0.737 in the same frames). The
// opposite hypothesis is measured once, and when it scores above the pose kept, the pose is not
// this frame's best explanation: the flip check opens, the poses are UNCERTAIN until the paired
// differences settle it, and the winner is tracked. Not when it is merely within the noise of a
// difference of two scores (significance_z() × flip_sd): the lamella on post's true re-found
// poses after a jump at 2.5 e-/px have their opposite within it, and the check held 3-4 frames
// of two `--quick` jump rows UNCERTAIN (recovery 1 -> 4 frames). One binned FFT and a walk on a
// surprising frame only; a target the turn does not fit (the needle tip) scores far below. A
// pattern of declared order > 1 is not checked here: its turned look is the target (its angle is
// declared modulo 360°/order). Nor while the pose is held (a frame the pattern did not explain)
// or off the continuity line (anchor open): there the frame is not the target's alone, and the
// line decides (twin_crosses_over_at_45deg, lamella on post at 2.5 e-/px: under the passing twin
// the opposite outscored the held true pose, 0.61 to 0.53, and the check took it: 84 TRACKING
// poses 15 px and 180° off where the base had 3).
template <class Place>
void Tracker::Impl::open_flip_on_jump(const PatternBank& bank, const Measurement& m, PoseEstimate& e, double t_s,
                                      const Place& place) noexcept {
  ContinuityAnchor::Line line;
  if (flip_open || !surprised || angle_order > 1 || held_frames > 0 || anchor.open() || !(cfg.max_false_probability > 0) ||
      loss.calibrating() || !m.valid || !anchor.line_at(t_s, line))
    return;
  // Only a pose off the last TRACKING poses' line (continuity_anchor.hpp): turn_180's look-alike
  // 15-17 px from it. A pose on it that the motion check doubts for its score alone is the target
  // (twin_crosses_down_at_45deg at 6 e-/px: opened on such a pose as the twin came near, the
  // check cost a frame the fit level learnt from and the twin was later TRACKING on 52 frames
  // where fc3265b had 0).
  if (std::hypot(e.x_px - line.x_px, e.y_px - line.y_px) <= line.tol_px) return;
  const Measurement f = opposite_of(bank, m, e);
  if (!f.valid || !(f.score > m.score)) return;
  PoseEstimate at;  // and the opposite on the line: the target the line leads to
  place(f, at);
  if (std::hypot(at.x_px - line.x_px, at.y_px - line.y_px) > line.tol_px) return;
  flip_open = true;
  flip_lead = FlipLead{};
  flip_circle = FlipLead{};
}

// One more frame of the flip check: the opposite hypothesis measured as the search measures it
// (binned FFT at φ+180° around the pose, the climb, walk and fit), its score difference added.
// Settled when the mean difference is significant: by the larger of the noise model's SD and
// the differences' own spread. Returns true when the opposite one won (m and e are then its).
template <class Place>
bool Tracker::Impl::settle_flip(const PatternBank& bank, Measurement& m, PoseEstimate& e, const Place& place) noexcept {
  Measurement f = opposite_of(bank, m, e);
  if (!f.valid) return false;
  const double d = static_cast<double>(m.score) - f.score;
  flip_lead.add(d);
  // The two hypotheses are scored on the same pixels, so their noise is largely shared (the
  // more alike they are, the more): the differences' own spread is the SD that counts, not
  // flip_sd's independent-score one (which would need ~80 frames at 2.5 e-/px); Student's t
  // with n − 1 degrees of freedom for the few frames it is measured on.
  int verdict = flip_lead.verdict(significance_z());
  if (shape_masked) {
    // A shape mask keeps the target's own pixels, and an outline at alpha 0.5 cuts a flat
    // target's rim in half: what tells it from itself turned by 180° (its edges against the
    // background) is largely outside the mask. The hypothesis with more signal under its mask
    // loses less of its score to the noise, so at low dose the masked score can prefer the
    // wrong one, steadily: the lamella on its post at 2.5 e-/px scored 0.60-0.62 turned 180°
    // and 18 px off against the target's 0.52-0.60, and the check kept it (52 of 60 poses false
    // TRACKING). The binned level's whole-circle scores (where the search located both) see
    // those edges: 0.66-0.68 against the target's 0.71-0.75 there, 0.08-0.12 in the target's
    // favour at 6 and 20 e-/px. The check decides only when both agree; else it stays open
    // (the poses followed, UNCERTAIN).
    const auto circle_score = [&](const Measurement& h) {
      half.correlate(bank.spectrum(h.j), maps.work());
      return find_peak(maps.work(), half.valid_w(), half.valid_h(), {h.ux / 2 - 1, h.uy / 2 - 1, h.ux / 2 + 2, h.uy / 2 + 2}).score;
    };
    flip_circle.add(static_cast<double>(circle_score(m)) - circle_score(f));
    e.angle_steps += 2;
    if (flip_circle.verdict(significance_z()) != verdict) verdict = 0;
  }
  if (verdict > 0) {
    flip_open = false;
  } else if (verdict < 0) {
    flip_open = false;
    const int steps = e.angle_steps;
    m = f;
    place(m, e);
    e.angle_steps = steps;
    return true;
  }
  return false;
}

// A pose followed again after a hold or a loss is reported TRACKING only when it is this
// frame's best explanation against the target turned 180° about it (opposite_of: the binned
// FFT at φ + 180° around the pose, the walk and the fit). While a target is lost or held its
// angle is free, and a partly symmetric pattern's own turned copy beside the true place fits
// it nearly as well: pose_envelope_probe spin_45deg_per_frame, the lamella on its post at
// 6 e⁻/px, followed again on a held ROI 16 px and 171–180° off at 0.72–0.78 while the target
// itself scored 0.79–0.82 there, TRACKING on 7 frames. The opposite only vetoes (UNCERTAIN,
// kReasonUnexplained): it is not taken, since under a passing twin it can outscore the true
// pose (open_flip_on_jump says how that went), and the flip check decides which to follow
// where it opens. The first TRACKING pose that leads its opposite ends the doubt. One binned
// FFT and a walk on the frames after a hold or loss only; a pattern of declared order > 1 is
// not checked (its turned look is the target).
void Tracker::Impl::judge_against_opposite(const PatternBank& bank, const Measurement& m, PoseEstimate& e) noexcept {
  if (!resumed_unvouched || e.state != TrackState::kTracking) return;
  if (angle_order > 1 || !(cfg.max_false_probability > 0) || loss.calibrating() || !m.valid) {
    resumed_unvouched = false;
    return;
  }
  const Measurement f = opposite_of(bank, m, e);
  if (f.valid && f.score > m.score) {
    e.state = TrackState::kUncertain;
    e.reason_bits |= kReasonUnexplained;
    return;
  }
  resumed_unvouched = false;
}

void Tracker::Impl::hold() noexcept {
  if (observer) observer->discard();
  filter.reset();
  tracking = false;
  ++held_frames;
  resumed_unvouched = true;
  // The next ROI at the last accepted pose, without velocity: following the unexplained
  // poses let the ROI wander onto a look-alike along the needle's body and be resumed there
  // (pipeline_test: median error 55 px). The score level stays, the weak-frame count restarts.
  motion.hold();
  loss.judge_reset();
  loss.set_held(true);
}

void Tracker::Impl::go_lost() noexcept {
  if (observer) observer->discard();
  filter.reset();
  tracking = false;
  if (held_frames > 0) {
    lost_after_hold = true;
    held_x_px = motion.x_px();
    held_y_px = motion.y_px();
    held_scale = scale;
  }
  held_frames = 0;
  resumed_unvouched = true;
  loss.set_held(false);
  loss.reset();
  motion.reset();
  last_known = false;
  still_doubt = parts_doubt = false;
  parts_before = {};
  blur_run_known = false;
}

bool Tracker::Impl::sheared_by_motion(const PoseFrame& frame, const Roi& roi, const PatternBank& bank, double at_scale) const noexcept {
  const std::int64_t span = frame.t_scan_end_ns - frame.t_scan_start_ns;
  double speed_px_s = 0, turn_deg_s = 0;
  if (span <= 0 || roi.h <= 0 || !recent.rates(1e-9 * static_cast<double>(frame.t_scan_start_ns), speed_px_s, turn_deg_s)) return false;
  const double rows = bank.size_px() * at_scale;
  const double rows_s = 1e-9 * static_cast<double>(span) / roi.h * rows;  // the target's rows, scanned
  // Moved along, and turned (the rows' far ends, half the target's size from its centre, swept).
  const double shear_px = rows_s * (speed_px_s + turn_deg_s * (std::numbers::pi / 180.0) * 0.5 * rows);
  return shear_px > kSearchShearPx;
}

void Tracker::Impl::scan_velocity(const PoseFrame& frame, const PatternBank& bank) noexcept {
  row_vx_px = row_vy_px = row_turn_deg = 0;
  const std::int64_t span = frame.t_scan_end_ns - frame.t_scan_start_ns;
  // Only on a stream the motion model vouches for: after a held frame or while the continuity
  // check is open the "velocity" may be a jump onto something else (a twin crossing over it),
  // and a bias computed from it would turn the pose further off (twin at 45°: 0 -> 50 false).
  if (!motion.motion_known() || !tracking || held_frames > 0 || anchor.open() || frame_period_s <= 0 || span <= 0 ||
      frame.roi.h <= 0)
    return;
  // The rates of the continuity trail over its three newest poses (TRACKING, explained by the
  // pattern), not the motion model's two-pose rate, which follows a hum wave's zigzag
  // (ContinuityAnchor::rates).
  double vx = 0, vy = 0, vphi = 0;
  if (!anchor.rates(vx, vy, vphi)) return;
  const double row_s = 1e-9 * static_cast<double>(span) / frame.roi.h;
  // The bias is linearised (scan_motion.hpp): a target turning by more than kScanTurnMaxDeg while
  // its rows are scanned is no small shear of the pattern (a spin of 45° a frame, the lamella on
  // its post at 6 e-/px: a TRACKING pose 10° off with the turn's bias taken out).
  if (std::fabs(vphi) * row_s * bank.size_px() * scale > kScanTurnMaxDeg) return;
  row_vx_px = vx * row_s;
  row_vy_px = vy * row_s;
  row_turn_deg = vphi * row_s;
}

// An accepted pose: the motion model and the recent score learn it, then the reported pose
// goes through the temporal filter (a pass-through unless tracker.filter is on), timed at
// mid-scan: with a varying dwell the ROI's centre is scanned mid-frame.
double Tracker::Impl::lag_shift_of(const PoseFrame& frame, std::uint8_t set) noexcept {
  frame_tau_ns = 0;
  if (!measure_tau && !check_told_tau) {
    frame_tau_ns = cfg.detector_tau_ns;
    // Told τ: the lag at this dwell against the pattern's (0 when either dwell is unknown).
    return frame.dwell_ns > 0 && set < pattern_lag_px.size()
               ? DetectorLag::px(cfg.detector_tau_ns, frame_dwell_ns) - pattern_lag_px[set]
               : 0.0;
  }
  // Measured: this frame's reading joins the estimate for its own pose (a first search frame
  // is corrected too); it is kept only if the pose is accepted. An ROI frame reads one band of
  // lines (~2.3k products, a few µs: the whole ROI every 8th frame), a full-field frame (the
  // start search, ms anyway) all its lines. A reading whose noise does not dominate its scene
  // is no reading (DetectorTauEstimator::read). A pattern set of unknown dwell counts the lag its
  // own noise showed at setup; a frame of unknown dwell is taken at the estimate's own. Told
  // τ: the same readings check it (told_checked_lag_shift).
  if (!frame.bad && frame.pixels != nullptr && !loss.calibrating()) {
    const int w = frame.roi.w, h = frame.roi.h;
    const bool full_field = w >= frame.field_w && h >= frame.field_h;
    const int step = line_correlation_row_step(w, h);
    const int band = full_field ? h : line_correlation_band_pairs(w);
    if (full_field || tau_band_line + 2 >= h) tau_band_line = 0;
    tau_estimate.read(line_correlation_sums(frame.pixels, w, h, w, step, tau_band_line, band), frame_dwell_ns);
    tau_band_line += band * step;
  } else {
    tau_estimate.read(LineCorrelationSums{}, frame_dwell_ns);  // nothing pending: the kept estimate
  }
  if (check_told_tau) return told_checked_lag_shift(set);
  if (!tau_estimate.has_reading()) return 0.0;  // the frames' lag not told yet: nothing to take out
  // The frames' correlation is not a low-pass's (dropped lines: the lag-2 check): their
  // lag is not known, and neither is what the pattern's would cancel. No lag taken out.
  if (!tau_estimate.consistent()) return 0.0;
  frame_tau_ns = tau_estimate.tau_ns();
  const double set_dwell = set < pattern_dwell_ns.size() ? pattern_dwell_ns[set] : 0.0;
  if (!(set_dwell > 0)) {
    const double pattern_rho = set < pattern_measured_rho.size() ? pattern_measured_rho[set] : 0.0;
    if (pattern_rho > 0 && std::fabs(tau_estimate.rho_at(frame_dwell_ns) - pattern_rho) < DetectorTauEstimator::kSameDetectorRho)
      return 0.0;
    return tau_estimate.lag_px(frame_dwell_ns) - pattern_rho / (1.0 - pattern_rho);
  }
  const double pattern_lag = tau_estimate.reference_dwell_ns() > 0 ? tau_estimate.lag_px(set_dwell) : 0.0;
  return tau_estimate.lag_px(frame_dwell_ns) - pattern_lag;
}

// Told τ checked: the frames' lag as told until their readings disagree with it (reported,
// tracker_impl.hpp); then, while the readings are a low-pass's (the lag-2 check), the lag they
// show — a detector swapped or its bandwidth switched since the calibration (τ 4 px told 1 px:
// the told lag left +1.6…+2.3 px in x, 9 TRACKING poses 3.2–3.9 px off over the probe's rows).
// Frames whose lines were dropped read a lag too, mostly not a low-pass's (the told lag stays);
// the few that pass the lag-2 check (every 4th line dropped under a told τ of 1–2 px) read 7–8
// px, beyond the lag sempose corrects (kMaxCorrectedLagPx), so their poses are UNCERTAIN
// (judge_lag): a slow detector at a short dwell reads the same (τ 1000 ns told 250 at the
// governor's 100 ns: 9 px of lag, the told 2 px taken out), and its poses, 7 px off, must not be
// TRACKING (NoFalseTracking.DroppedLinesDoNotOverruleAToldDetectorTau). A set overruled at setup counts
// its own reading, and a reading within kSameDetectorRho of the frames' is the same detector at
// the same dwell: nothing between them. A set not overruled: its told lag.
double Tracker::Impl::told_checked_lag_shift(std::uint8_t set) noexcept {
  frame_tau_ns = cfg.detector_tau_ns;
  if (!(frame_dwell_ns > 0) || set >= pattern_lag_px.size()) return 0.0;
  const double told_rho = std::exp(-frame_dwell_ns / cfg.detector_tau_ns);
  if (!frames_disagree && tau_estimate.frames_kept() >= DetectorTauEstimator::kToldCheckFrames &&
      DetectorTauEstimator::told_disagrees(told_rho, tau_estimate.rho_at(frame_dwell_ns))) {
    frames_disagree = true;
    frames_disagree_status.store(true, std::memory_order_relaxed);
  }
  const bool measured = frames_disagree && tau_estimate.has_reading() && tau_estimate.consistent();
  frames_lag_measured.store(measured, std::memory_order_relaxed);
  if (measured) frame_tau_ns = tau_estimate.tau_ns();
  const double frame_rho = measured ? tau_estimate.rho_at(frame_dwell_ns) : told_rho;
  const double frame_lag = measured ? tau_estimate.lag_px(frame_dwell_ns) : DetectorLag::px(cfg.detector_tau_ns, frame_dwell_ns);
  if (!pattern_told_overruled[set]) return frame_lag - pattern_lag_px[set];
  const double pattern_rho = pattern_measured_rho[set];
  if (pattern_rho > 0 && std::fabs(frame_rho - pattern_rho) < DetectorTauEstimator::kSameDetectorRho) return 0.0;
  return frame_lag - DetectorTauEstimator::lag_of_rho(pattern_rho);
}

// The detector's τ in use (told, measured, or measured in place of a told one the frames
// contradict) and the pattern's lag (what this frame's shift leaves of the frames' lag at its
// dwell) give the shortest dwell at which the frames lag the pattern by at most
// kFloorLagShare × kMaxCorrectedLagPx: ρ = e^(−d/τ) ≤ L / (1 + L), L that lag plus the
// pattern's. The governor keeps a target's ROI dwell at or above it (TrackingStep): at the
// governor's shortest dwell a slow detector's lag is beyond correction and every pose UNCERTAIN
// (the simulator with sim.detector_tau_ns 1000 at 100 ns: 9.4 px, 0.2 % TRACKING). The share
// leaves the reading's noise room below the limit. 0: no lag known (a fast detector, τ untold and
// not yet read, or readings that are no low-pass's).
void Tracker::Impl::update_dwell_floor() noexcept {
  const double tau_ns = frame_tau_ns;
  if (!(tau_ns > 0) || !(frame_dwell_ns > 0)) {
    correctable_dwell_floor_ns.store(0, std::memory_order_relaxed);
    return;
  }
  const double pattern_lag = std::max(0.0, DetectorLag::px(tau_ns, frame_dwell_ns) - lag_shift_px);
  const double lag = pattern_lag + Tracker::kFloorLagShare * Tracker::kMaxCorrectedLagPx;
  const double floor_ns = tau_ns * std::log((1.0 + lag) / lag);
  correctable_dwell_floor_ns.store(static_cast<std::uint32_t>(std::min(std::ceil(floor_ns), 4.0e9)), std::memory_order_relaxed);
}

// The lag taken out of x is the low-pass's mean delay; the smeared target's correlation peak
// moves less (the kernel's mode is at 0) by a share that depends on its detail and grows with
// the delay (−0.02…−0.22 px at 1 px of lag, −0.3…−1.3 at 4; 3–6 px at 6–12 px, TRACKING on
// σx 0.5 px: hostile round 12, an untold slow detector). Beyond the range probed the pose is
// not vouched for; the count and the largest lag go to the status (run and replay print them).
void Tracker::Impl::judge_lag(PoseEstimate& e) noexcept {
  const double lag = std::fabs(lag_shift_px);
  if (!(lag > Tracker::kMaxCorrectedLagPx) || (e.state != TrackState::kTracking && e.state != TrackState::kUncertain)) return;
  lag_beyond_frames.store(lag_beyond_frames.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  if (lag > lag_beyond_max_px.load(std::memory_order_relaxed)) lag_beyond_max_px.store(lag, std::memory_order_relaxed);
  if (e.state == TrackState::kTracking) {
    e.state = TrackState::kUncertain;
    e.reason_bits |= kReasonUnexplained;
  }
}

void Tracker::Impl::accept(PoseEstimate& e, const PoseFrame& frame, bool fresh, double level_cap) noexcept {
  e.state = TrackState::kTracking;
  if (measure_tau || check_told_tau) {
    tau_estimate.keep();
    measured_rho.store(tau_estimate.rho_at(tau_estimate.reference_dwell_ns()), std::memory_order_relaxed);
    measured_tau_px.store(tau_estimate.tau_px(), std::memory_order_relaxed);
    measured_tau_ns.store(tau_estimate.tau_ns(), std::memory_order_relaxed);
    measured_tau_frames.store(tau_estimate.frames_kept(), std::memory_order_relaxed);
    measured_lag2_excess.store(tau_estimate.lag2_excess(), std::memory_order_relaxed);
    measured_inconsistent.store(!tau_estimate.consistent(), std::memory_order_relaxed);
  }
  held_frames = 0;
  loss.set_held(false);
  motion.accept(e.x_px, e.y_px, e.phi_deg, fresh, frame_dwell_ns, e.score);
  loss.accepted(static_cast<float>(std::min<double>(e.score, level_cap)));
  tracking = true;
  if (fresh) {
    still_doubt = parts_doubt = false;
    parts_before = {};
  }
  last_known = true;
  last_x = e.x_px;
  last_y = e.y_px;
  last_phi = e.phi_deg;
  last_score = e.score;
  last_dwell_ns = frame_dwell_ns;
  if (fresh) filter.reset();
  const double t_s = 0.5e-9 * (static_cast<double>(frame.t_scan_start_ns) + static_cast<double>(frame.t_scan_end_ns));
  PoseSample f = filter.update({t_s, e.x_px, e.y_px, e.phi_deg});
  // A filter that cannot follow the motion (tuned loosely, within its ranges: meas_sigma_px 100,
  // gate_sigma 1000) lagged the target by 120-224 px while every pose was TRACKING on its
  // measurement (hostile round 13). Beyond the false-pose distance from this frame's measurement
  // it starts again from it; within it, a filtered pose more than half that distance away is
  // not vouched for (Tracker::update).
  if (std::hypot(f.x_px - e.x_px, f.y_px - e.y_px) > LossPolicy::kFalsePx ||
      std::fabs(rt::wrap_deg(f.phi_deg - e.phi_deg)) > LossPolicy::kFalseDeg) {
    filter.reset();
    f = filter.update({t_s, e.x_px, e.y_px, e.phi_deg});
  }
  e.x_px = f.x_px;
  e.y_px = f.y_px;
  e.phi_deg = f.phi_deg;
}

PoseEstimate Tracker::Impl::update(const PoseFrame& frame) noexcept {
  PoseEstimate e;
  jump_declined = false;
  fit_in_excess = false;
  const std::uint8_t set = active.load(std::memory_order_relaxed);
  e.pattern_set = set;
  if (set < symmetry.size()) angle_order = symmetry[set].order;
  e.angle_order = static_cast<std::uint8_t>(angle_order);
  e.x_px = motion.x_px();
  e.y_px = motion.y_px();
  e.phi_deg = motion.phi_deg();
  frame_dwell_ns = static_cast<double>(frame.dwell_ns);
  row_vx_px = row_vy_px = row_turn_deg = 0;  // set by scan_velocity() on an ROI frame only
  frame_scan_motion = nullptr;
  {
    const double mid_s = 0.5e-9 * (static_cast<double>(frame.t_scan_start_ns) + static_cast<double>(frame.t_scan_end_ns));
    frame_period_s = last_mid_s > 0 && mid_s > last_mid_s ? mid_s - last_mid_s : 0.0;
    last_mid_s = mid_s;
  }
  lag_shift_px = lag_shift_of(frame, set);
  update_dwell_floor();
  if (frame.field_w > 0 && frame.field_h > 0) {
    field.field_w = frame.field_w;
    field.field_h = frame.field_h;
  }
  const Roi& roi = frame.roi;
  const std::uint16_t* px = frame.pixels;
  // A frame repeating the last one although scanned elsewhere or while the stream predicts a
  // move (a frozen frame buffer) is a bad frame the source did not flag: nothing in it is new.
  const bool expects_change =
      tracking && motion.has_velocity() &&
      (std::hypot(motion.predicted_x_px() - motion.x_px(), motion.predicted_y_px() - motion.y_px()) >= kStaleMovePx ||
       std::fabs(rt::wrap_deg(motion.predicted_phi_deg() - motion.phi_deg())) >= kStaleTurnDeg);
  if (frame.bad || px == nullptr || roi.w <= 0 || roi.h <= 0 ||
      stale.repeats(px, roi.x, roi.y, roi.w, roi.h, expects_change)) {
    e.state = tracking ? TrackState::kLost : TrackState::kAcquiring;
    e.reason_bits = kReasonBadFrame;
    return e;
  }
  const PatternBank& bank = frame_bank(set);
  attainable_factor = set < pattern_factor.size() ? pattern_factor[set] : 1.0;
  shape_masked = set < banks.size() && banks[set]->has_shape();
  if (set < set_score_samples.size()) score_samples = set_score_samples[set];
  masked_bank = shape_masked ? &bank : nullptr;
  const bool full_field = field.is_full_field(roi.x, roi.y, roi.w, roi.h);
  bool commanded_search = false;
  if (reacquire.exchange(false, std::memory_order_relaxed)) {
    commanded_search = reacquire_commanded.exchange(false, std::memory_order_relaxed);
    go_lost();
    flip_open = false;
    search_n = 0;
    searches_rejected = 0;
    // Commanded, or a new magnification: the target's look may have changed; the new
    // pattern set has its own noise floors and is matched at its own size first. sempose's own
    // re-search (a look-alike target on this one's place: same target, same detector) carries
    // the stream's pose noise as after a loss, so its search frame is judged against it rather
    // than waiting, as a first start's does, for an ROI frame to confirm it.
    loss.forget_target();
    fit_level.forget();
    explained_level.forget();
    refind_level = 0;
    refind_research = false;
    lost_after_hold = away_from_held = lost_on_tear = false;
    tear_level = 0;
    blur_level.forget();
    scale_sigma_level.forget();
    if (commanded_search) motion.forget_noise();
    scale = expected_scale.load(std::memory_order_relaxed);
    scale_reference = scale;
    scale_tracked = false;
    use_noise_floors_of(set);
    if (!full_field) {
      e.state = TrackState::kAcquiring;
      e.reason_bits = kReasonCommanded;
      return e;
    }
  }

  // A full-field frame while tracking (scanned before the last search's result reached the
  // scan plan): track in its crop at the predicted pose instead of searching again.
  Roi scored = roi;
  const bool on_target = tracking || held_frames > 0;
  if (full_field && on_target) {
    const Roi crop = motion.window_at_prediction(std::min(sizes.roi_px, roi.w), std::min(sizes.roi_px, roi.h), roi.w, roi.h);
    px += static_cast<std::size_t>(crop.y) * roi.w + crop.x;
    scored = {roi.x + crop.x, roi.y + crop.y, crop.w, crop.h};
  }
  if (!on_target || scored.w > sizes.roi_fft_px || scored.h > sizes.roi_fft_px) {
    int rx = 0, ry = 0;
    e.searched = true;
    tracking_speed_px = -1;
    const bool prior_known = motion.last_angle().known;
    const AnglePrior angle_before = motion.last_angle();  // accept() below overwrites it
    bool turned = false;
    const double t_mid_s = 0.5e-9 * (static_cast<double>(frame.t_scan_start_ns) + static_cast<double>(frame.t_scan_end_ns));
    double found_scale = scale;
    // The expected scale is a prior: the SELECT's (else 1) for a new target, the last tracked
    // one after a loss. One level only for a new target whose size the SELECT told; after a loss
    // the levels around the last tracked scale: a magnification step without SELECT loses the
    // target, and one level at the old size found the best match of the old size, a wrong pose
    // the frames after it kept (pose_envelope_probe scale_step_*: the needle tip 10-11 px off, the
    // lamella on post 24-28 px and 87° off, TRACKING on 21 and 34 of 80 frames at 6 e-/px).
    //
    // The last tracked scale is a prior, not a fact: a scale that drifted off while the target
    // was followed UNCERTAIN (a pattern of another specimen of the target's kind drew it 1.00 ->
    // 0.90 over 40 frames) finds the target at that scale only, below the level it kept, and
    // every search after it refused it (~970 in a row, found probing: `run` over a looped
    // recording). After kScalePriorLapse rejected searches the levels go back around the
    // expected scale, the SELECT's or the configured one.
    if (scale_tracked && searches_rejected >= kScalePriorLapse) scale_tracked = false;
    const ScalePrior scale_prior{scale_tracked ? scale : expected_scale.load(std::memory_order_relaxed),
                                 !scale_tracked && scale_told.load(std::memory_order_relaxed)};
    // The other targets' objects, in this frame's coordinates: not to be taken by this one.
    HeldPlaces held = frame.held_by_others;
    for (int i = 0; i < held.count && i < kMaxHeldPlaces; ++i) {
      held.x_px[i] -= roi.x;
      held.y_px[i] -= roi.y;
    }
    if (start_r > 0 && !ever_tracking) {
      held.within_x_px = start_x - roi.x;
      held.within_y_px = start_y - roi.y;
      held.within_r_px = start_r;
    }
    const Measurement m = search.search(bank, px, roi.w, roi.h, frame.bits, motion.last_angle(), scale_prior, rx, ry,
                                        found_scale, held);
    if (m.valid) {
      to_estimate(m, roi.x + rx, roi.y + ry, e);
      unlag(e);
      // A pattern of declared order n: the n looks are one, so the angle reported is the look
      // nearest the last one (within ±180°/n of it), the continuity a controller reads; with no
      // last angle the search's own choice, which no frame can check (README: Symmetric targets).
      if (angle_order > 1 && angle_before.known) {
        const double turn = 360.0 / angle_order;
        e.phi_deg = rt::wrap_deg(e.phi_deg + turn * std::round(std::remainder(angle_before.phi_deg - e.phi_deg, 360.0) / turn));
        e.meas_phi_deg = e.phi_deg;
      }
    }
    e.scale = m.valid ? std::clamp(found_scale, kScaleMin, kScaleMax) : scale;
    const double attainable = m.valid ? attainable_score(px, roi.w, roi.h, e.x_px + lag_shift_px - roi.x, e.y_px - roi.y, m.j) : 0.0;
    if (m.valid) e.chi2 = normalised_chi2(e.score, attainable);
    const Loaded loaded = loss.found(m, attainable) ? search_sigma(bank, m, px, roi, frame.bits, e) : Loaded{};
    if (loss.found(m, attainable) && !search_settled(m, e)) {
      // Found, but not told from a look-alike elsewhere yet: reported UNCERTAIN, searched again.
      e.state = TrackState::kUncertain;
      go_lost();
    } else if (loss.found(m, attainable)) {
      const bool unconfirmed = first_pose_unconfirmed();  // before accept() teaches the motion model
      // The target's level from a search frame at most the attainable score: a score above it
      // shares the frame's noise with the pattern (a pattern cut from this very frame scores
      // 0.95 there and 0.55-0.6 on every later frame, read as a fall to a look-alike).
      accept(e, frame, true, cfg.attainable_pattern_noise && attainable > 0 ? attainable : 1.0);
      scale = e.scale;  // tracking starts at the scale the search found
      untorn_scale = scale;
      scale_held = scale_vouched = false;
      scale_held_frames = 0;
      scale_tracked = true;
      searches_rejected = 0;
      scale_reference = scale;
      const bool at_edge = at_field_edge(e, e.scale);
      turned = turned_off_line(m, e, t_mid_s);
      open_flip_check(m, prior_known && std::fabs(rt::wrap_deg(e.phi_deg - angle_before.phi_deg)) <= 90.0, at_edge);
      // The search frame's pose is judged like a tracked one (trusted_pose: below the explained
      // bound it waits for the stream's pose noise; above it by its own σ, search_sigma).
      if (flip_open || unconfirmed || !trusted_pose(e, Innovation{})) e.state = TrackState::kUncertain;
      if (at_edge) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonOutOfField;
      }
      // The field scan saw the target's rows at places the rigid pattern does not join (a torn
      // or glitched scan; a target moving during the long field scan, whose motion is not known
      // here): its pose is not vouched for until an ROI frame confirms it.
      if (e.state == TrackState::kTracking && loaded.valid && torn(loaded.at, bank, loaded.used_scale, 0, 0)) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonUnexplained;
      }
      judge_fit(e, set < off_share.size() ? off_share[set] : 1.0);
      // The scan tore the frame that lost the target (lost_on_tear): the field scan after it may
      // be torn where no cut of the window can show it, so its pose waits for an ROI frame.
      if (lost_on_tear && e.state == TrackState::kTracking) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonUnexplained;
      }
      lost_on_tear = false;
      if (e.state == TrackState::kTracking && sheared_by_motion(frame, roi, bank, e.scale)) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonUnexplained;
      }
      check_tear_level(m, e);
      // A re-find after a loss (the target's level kept through it): judged against that level.
      if (explained_level.known() && !loss.calibrating()) {
        refind_level = explained_level.chi2();
        refind_below_frames = 0;
      }
      frame_explained = attainable > 0 ? e.score / attainable : 0.0;
      check_refind_level(e);
      judge_lag(e);
    } else {
      e.state = TrackState::kAcquiring;
      ++searches_rejected;
      // Not found is a low score too when it is only below the field's floor, the attainable
      // score or the target's own level.
      e.reason_bits = m.valid ? static_cast<std::uint8_t>(loss.weak_reasons(m) | kReasonLowScore)
                              : static_cast<std::uint8_t>(kReasonFlatFrame);
      go_lost();
    }
    // A re-acquisition off the last TRACKING poses' line while the line's place holds a
    // hypothesis scoring with it: a twin that covered the target, or the target itself.
    // (keep_continuity then holds it UNCERTAIN until the poses keep to the line.)
    line_rival = (e.state == TrackState::kTracking || e.state == TrackState::kUncertain) && tracking &&
                 (turned || rival_on_line(bank, px, roi, frame.bits, e, angle_before, t_mid_s));
    found_after_hold = false;
    if (e.state == TrackState::kTracking || e.state == TrackState::kUncertain) {
      away_from_held = lost_after_hold && off_held_place(e);
      found_after_hold = lost_after_hold;
      // A rival keeps the line, and with it where the target was held: the ROI sent back to the
      // line's place (keep_continuity) may lose the covered target again without holding it, and
      // the search after that must still judge its winner against the held place (the needle tip
      // under the lamella on post at 2.5 e-/px: the lamella's edge taken TRACKING 100-170 px off
      // on the fourth such search, once the line had aged out).
      lost_after_hold = lost_after_hold && line_rival;
      away_frames = 0;
      away_excess_sum = 0;
      if (away_from_held) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonUnexplained;
      }
    }
    // The search a controller's command started, run on this full-field frame: its pose says
    // so (reason 32) and waits for the next frame to confirm it, as one on an ROI frame in
    // flight is ACQUIRING with reason 32. Without the mark a REACQUIRE whose search found the
    // target at once left no trace in the pose stream (system test, under slow TCG).
    if (commanded_search) {
      e.reason_bits |= kReasonCommanded;
      if (e.state == TrackState::kTracking) e.state = TrackState::kUncertain;
    }
    return e;
  }

  // Tracking: one forward FFT for this ROI, then the walk.
  const int pattern_px = sizes.pattern_px;
  const bool rescaled = std::fabs(scale - 1.0) > kRescaleFrom;
  const double used_scale = rescaled ? scale : 1.0;  // the scale the ROI is loaded at
  const std::uint16_t* load_px = px;
  std::ptrdiff_t load_stride = roi.w;
  int load_bits = frame.bits;
  if (rescaled && scored.w >= pattern_px && scored.h >= pattern_px) {
    load_px = rescaler.rescale(px, scored.w, scored.h, roi.w, frame.bits, used_scale);
    load_stride = std::min(scored.w, sizes.roi_fft_px);
    load_bits = RoiRescaler::out_bits(frame.bits);
  }
  ++load_seq;  // (the split cache's key: what the loader holds)
  if (scored.w < pattern_px || scored.h < pattern_px || !loader.load(load_px, scored.w, scored.h, load_stride, load_bits)) {
    e.state = TrackState::kLost;
    e.reason_bits = static_cast<std::uint8_t>((scored.w < pattern_px || scored.h < pattern_px) ? kReasonOutOfField
                                                                                                  : kReasonFlatFrame);
    e.score = 0;
    go_lost();
    return e;
  }
  // A measurement's pose in the field (from the resampled ROI back to the scanned one).
  auto place = [&](const Measurement& mm, PoseEstimate& out) {
    to_estimate(mm, scored.x, scored.y, out);
    if (rescaled) {
      out.x_px = scored.x + RoiRescaler::to_raw(out.x_px - scored.x, std::min(scored.w, sizes.roi_fft_px), used_scale);
      out.y_px = scored.y + RoiRescaler::to_raw(out.y_px - scored.y, std::min(scored.h, sizes.roi_fft_px), used_scale);
      out.meas_x_px = out.x_px;
      out.meas_y_px = out.y_px;
    }
    unlag(out);
  };
  bool swept = false;
  rival_within_noise = false;
  surprised = false;
  scan_velocity(frame, bank);
  frame_scan_motion = set < scan_motion.size() ? &scan_motion[set] : nullptr;
  Measurement m = track(bank, swept, set, {load_px, load_stride});
  place(m, e);
  // The loaded ROI's origin in the field (a rescaled ROI is resampled about its centre).
  const int loaded_w = std::min(scored.w, sizes.roi_fft_px), loaded_h = std::min(scored.h, sizes.roi_fft_px);
  // (Its origin where the target's true place is: the frame shows it lag_shift_px further on.)
  check_motion(bank, m, e, swept, scored.x - lag_shift_px + (rescaled ? 0.5 * (loaded_w - 1) * (1.0 - used_scale) : 0.0),
               scored.y + (rescaled ? 0.5 * (loaded_h - 1) * (1.0 - used_scale) : 0.0), used_scale, place);
  // A pose turned from the line of an open continuity check (a turned re-acquisition kept it
  // open: turned_off_line) measures its opposite hypothesis too, the one the line predicts: the
  // flip check takes it when it wins (twin_crosses_over_at_45deg: the pose left on the target's
  // own 180° look-alike 15 px off once the twin had passed, the target itself scoring 0.94 to its
  // 0.75-0.83). Only UNCERTAIN poses are at stake: the line vouches for the result.
  if (!flip_open && cfg.max_false_probability > 0 && anchor.open()) {
    ContinuityAnchor::Line line;
    const double t_s = 0.5e-9 * (static_cast<double>(frame.t_scan_start_ns) + static_cast<double>(frame.t_scan_end_ns));
    if (anchor.line_at(t_s, line) && ContinuityAnchor::turned(e.phi_deg, line)) {
      flip_open = true;
      flip_lead = FlipLead{};
      flip_circle = FlipLead{};
    }
  }
  open_flip_on_jump(bank, m, e, 0.5e-9 * (static_cast<double>(frame.t_scan_start_ns) + static_cast<double>(frame.t_scan_end_ns)),
                    place);
  // The flip check before the scale probe and σ, which read the hypothesis kept.
  const bool flipped = flip_open && settle_flip(bank, m, e, place);
  const ScaleReading reading = scale_probe.read(bank, m);
  const PoseSigma sigma = uncertainty.estimate(bank, m, reading.valid ? reading.factor : 1.0);
  set_sigma(sigma, used_scale, e);
  frame_scale_sigma = sigma.valid && reading.valid ? e.sigma_scale * (frame_dwell_ns > 0 ? std::sqrt(frame_dwell_ns) : 1.0) : 0.0;
  widen_for_blur(sigma, e);
  e.scale = reading.valid ? used_scale * reading.factor : scale;
  // The attainable score is ≤ 1, so a score at or above the explained check's upper bound
  // passes whatever it is, and one at or above the off-pose share is never below the target's
  // fit level by more than a pose off the target would be (judge_fit): measured only when it
  // can matter (~30 µs a frame saved), and on every kFitSampleEvery-th ROI frame for the level,
  // whatever it scores (learning only from low-scoring frames would bias the level up).
  const double off = set < off_share.size() ? off_share[set] : 1.0;
  const bool fit_sample = ++fit_frames % kFitSampleEvery == 0;
  const bool judged = e.score < std::max(loss.explained_bound(), off) || fit_sample;
  // s / a is read for its level until known, then with fit_level, and on every frame a re-find's
  // check is open (check_refind_level): e.chi2 stays what the sampling above gives.
  const bool explained_sample = fit_sample || refind_level > 0 || (!explained_level.known() && !loss.calibrating());
  frame_explained = 0;
  if (judged || explained_sample) {
    const double attainable = attainable_score(frame.pixels, roi.w, roi.h, e.x_px + lag_shift_px - roi.x, e.y_px - roi.y, m.j);
    if (judged) {
      e.chi2 = normalised_chi2(e.score, attainable);
      if (e.score < loss.explained_bound()) m.attainable = static_cast<float>(attainable);
    }
    if (explained_sample && attainable > 0) frame_explained = e.score / attainable;
  }
  if (m.unsettled || m.on_window_edge) e.reason_bits |= kReasonAngleUnsettled;
  if (motion.prediction_outside(field.field_w, field.field_h)) e.reason_bits |= kReasonOutOfField;
  // The split check's allowance for the target's own motion and size (before accept() moves the
  // motion model on): the accepted frame's check and the lost frame's (lost_on_tear) use it.
  const SplitAllowance allow = split_allowance(frame, e, roi.h, used_scale);
  switch (loss.judge(m)) {
    case FrameVerdict::kAccept: {
      // Where the pose landed against a prediction made from two ROI poses (before the motion
      // model learns it): trusted_pose weighs it.
      Innovation innov;
      if (!flipped && motion.prediction_from_roi_poses())
        innov = {true, motion.innovation_px(e.x_px, e.y_px), motion.innovation_deg(e.phi_deg)};
      const bool fell = fell_below_search_level(m.score);  // against the level before this frame
      const bool fell_still = fell_while_still(e);          // against the last accepted pose
      const bool below_level = loss.below_own_level(m.score);  // against the level before this frame
      accept(e, frame, flipped);  // the motion so far was the other hypothesis's
      // A torn frame's scale reading is torn too, and it is not only the rate that must not learn
      // it: a tear across the lines through the target's middle reads as a change of size (the
      // lamella on its post, the lower half 8 px down: parts 2 px apart at 6.3 SD on the first
      // torn frame, whose reading still moved the scale 1.00 → 1.02; the next step closed the
      // steady-scale gate, and at 1.06 the stretched pattern fitted both halves, TRACKING
      // 3.7-3.9 px off on 7 frames, pose_envelope_probe half_shifted_y_8px). So a frame found
      // torn, followed TRACKING or UNCERTAIN, holds the tracked scale, and the hold lasts until the
      // parts lie clearly together again (every cut within kTogetherZ SDs: at 6 e-/px the second
      // torn frame's parts were 2.8 SD apart, below the torn bound, and its reading restarted
      // the drift): the gate stays open and each torn frame is judged at the untorn size. Only a
      // scale some frame's parts vouched for is held (a search on a torn frame took 1.026 and
      // held it, every frame after apart at it), and for at most kMaxScaleHold frames (a real
      // step in size keeps the parts apart too; then the scale follows it as before).
      bool together = false;
      const bool split_apart = allow.steady_scale && torn(m, bank, used_scale, allow.shear_per_row, allow.scale_per_row, &together);
      scale_held = scale_vouched && (split_apart || (scale_held && !together)) && scale_held_frames < kMaxScaleHold;
      scale_held_frames = scale_held ? scale_held_frames + 1 : 0;
      if (allow.steady_scale && together) scale_vouched = true;
      if (reading.valid && !scale_held) scale = std::clamp(scale + kScaleGain * (e.scale - scale), kScaleMin, kScaleMax);
      // Followed either way; reported TRACKING only when the pose is that good (UNCERTAIN:
      // at 1 e-/px a pose can sit on a neighbouring maximum 4-8 px off at the target's score).
      if (flip_open || rival_within_noise || jump_declined || fell || fell_still || !trusted_pose(e, innov)) e.state = TrackState::kUncertain;
      // Followed (the next ROI is centred on it), not vouched for; gated as the field's edge is.
      if (m.on_window_edge && cfg.max_false_probability > 0 && !loss.calibrating()) e.state = TrackState::kUncertain;
      // So is an angle the walk left at its per-frame bound with no sweep around it: the angle's
      // peak may lie beyond, and the stream followed the bound frame after frame (max_angle_steps_
      // per_frame 1, recover_sweep_deg 0, a needle spinning 8° a frame: TRACKING 10.6-14.8° off on
      // σφ 1.6-2.7°; hostile round 12). After a sweep the angle kept is the best of its range.
      if (m.unsettled && !swept && cfg.max_false_probability > 0 && !loss.calibrating()) e.state = TrackState::kUncertain;
      if (at_field_edge(e, used_scale)) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonOutOfField;
      }
      // The target's size beyond the scales the tracker follows (the ROI cannot hold it): the
      // tracked scale stops at kScaleMin / kScaleMax while the target grows or shrinks on, and
      // the pose drifts with the mismatch (pose_envelope_probe --case scale_ramp: a ramp to 1.6 /
      // 0.6, the needle tip 3-6.7 px off from truth 1.51 / 0.65 on, TRACKING). The tracked scale
      // pinned at the range's end and this frame's reading beyond it: the pattern no longer models
      // the target's size (the reading itself goes at most ScaleProbe::kStep past the scale loaded).
      if (reading.valid && ((scale >= kScaleMax && e.scale > kScaleMax) || (scale <= kScaleMin && e.scale < kScaleMin))) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonUnexplained;
      }
      if (split_apart && e.state == TrackState::kTracking) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonUnexplained;
      }
      if (parts_doubted(m, bank, used_scale, e) && e.state == TrackState::kTracking) {
        e.state = TrackState::kUncertain;
        e.reason_bits |= kReasonUnexplained;
      }
      judge_fit(e, off);
      judge_scale_sigma(e);
      judge_scale_drift(bank, m, used_scale, e);
      judge_against_opposite(bank, m, e);
      if (away_from_held) {
        if (!(e.chi2 > 0)) e.chi2 = normalised_chi2(e.score, attainable_score(frame.pixels, roi.w, roi.h, e.x_px + lag_shift_px - roi.x, e.y_px - roi.y, m.j));
        judge_away_from_held(e);
      }
      check_tear_level(m, e);
      check_refind_level(e);
      judge_lag(e);
      // Learnt from frames tracked well only: a pose the rules doubt would teach the level its lie.
      if (fit_sample && e.state == TrackState::kTracking && e.reason_bits == 0) fit_level.learn(e.chi2);
      if (frame_explained > 0 && refind_level == 0 && e.state == TrackState::kTracking && e.reason_bits == 0)
        explained_level.learn(frame_explained);
      if (e.state == TrackState::kTracking && e.reason_bits == 0 && !blur_widened) {
        blur_level.learn(frame_blur);
        scale_sigma_level.learn(frame_scale_sigma);
      }
      if (e.state == TrackState::kTracking) {
        tracking_speed_px = std::hypot(motion.predicted_x_px() - motion.x_px(), motion.predicted_y_px() - motion.y_px());
        lost_on_tear = false;  // held through the tear and followed again: no search to doubt
      }
      if (!split_apart) {
        scale_step = scale - untorn_scale;
        scale_rate += kScaleRateGain * (scale_step - scale_rate);
        untorn_scale = scale;
      }
      // A good frame teaches the appearance model (RT: sums into a preallocated batch). It reads
      // the pixels the walk was scored on (the ROI resampled to the pattern's size if rescaled).
      if (learning && e.reason_bits == 0 && e.state == TrackState::kTracking && m.score >= cfg.appearance.min_score) {
        const double c = (pattern_px - 1) / 2.0;
        observer->observe(set, scorer.roi(), scorer.roi_w(), scorer.roi_h(), load_px, load_stride, load_bits, m.ux + m.dx + c,
                          m.uy + m.dy + c, (m.j + m.dj) * angles.step_deg, e.x_px, e.y_px);
      }
      // A pose followed below the target's own level and not reported may have taken the ROI onto
      // something else, as a hold does: the next TRACKING pose is checked against its opposite
      // again (judge_against_opposite). pose_envelope_probe spin_15deg_per_frame, the lamella on
      // its post at 20 e-/px: the frame after the first TRACKING pose (0.93) followed a turned
      // neighbour 16 px and 82° off at 0.70, UNCERTAIN; the next took that one's 180° turned copy,
      // 15 px and 175° off at 0.78, TRACKING. Re-armed on every UNCERTAIN frame instead, the
      // opposite vetoed true poses at 1 e-/px (twin_crosses_over_at_45deg: 27 -> 6 % TRACKING).
      if (e.state == TrackState::kUncertain && below_level) resumed_unvouched = true;
      if (refind_research) {
        refind_research = false;
        go_lost();  // reported UNCERTAIN, as followed; the next frame searches the field
      }
      break;
    }
    case FrameVerdict::kLost:
      e.reason_bits |= loss.weak_reasons(m);
      e.state = TrackState::kLost;
      // A tear whose parts the split check cannot pair (the lower half 20 px over: the pose on
      // one part, the other beyond the cuts' reach) shows as a jump the score does not vouch for.
      if (m.valid && ((allow.steady_scale && torn(m, bank, used_scale, allow.shear_per_row, allow.scale_per_row)) ||
                      (m.implausible && e.reason_bits == kReasonUnexplained))) {
        lost_on_tear = true;
        // A second loss while the glitch lasts finds the level already forgotten: the first kept.
        if (loss.recent_level() > 0) {
          tear_level = loss.recent_level();
          tear_margin = std::max(loss.confirm_margin(), significance_z() * flip_sd(tear_level));
          tear_below_frames = 0;
        }
      }
      if (loss.only_unexplained(m) && held_frames < kMaxHeldFrames) hold();
      else go_lost();
      break;
    case FrameVerdict::kCoast:
      // Not yet lost: report the measurement with its reasons, coast on the motion model. A
      // weak measurement is not a pose to drive with: UNCERTAIN (it was TRACKING with reasons).
      e.reason_bits |= loss.weak_reasons(m);
      e.state = TrackState::kUncertain;
      motion.coast();
      break;
  }
  return e;
}

// A TRACKING pose the pattern fits worse than it fits the target, by more than noise and by more
// than a pose off the target by the false-pose radius would: UNCERTAIN, kReasonUnexplained. No
// other rule sees such a pose while its score clears 0.7 × the target's level and the explained
// check's bound: the lamella on post's re-acquisition beside a dark occluder took it turned
// ~100° and 10 px off at 0.725 (the target's level 0.94), χ² 39.7 where its tracked frames
// read ~3.3, and held it ~90 frames at χ² 15-18.
// - *significant*: χ² above the target's own level (fit_level.hpp, learnt on frames it tracked
//   well) by z SDs of a frame's log χ² about it (z: significance_z(), the rate a false pose is
//   allowed); the SD at least the detector noise's alone: log(1 − s²) moves by
//   2s·SD(s)/(1 − s²) = 2s/√N_eff, and log(1 − a²) as much again.
// - *material*: the score below what the target reaches in this window at its level, s_t² =
//   1 − level × (1 − a²) (1 − a² = (1 − s²)/χ², the residual the noise model predicts here),
//   times the best share a pose kFalsePx / kFalseDeg off reaches (off_pose_score.hpp). Without
//   it the rule flagged true poses whose χ² rose 8-40 % on a fast target's scan (38 frames of
//   `pose_accuracy_bench --quick`): significant against a steady stream's narrow spread, but
//   nowhere near what a pose 3 px off leaves unexplained.
void Tracker::Impl::judge_fit(PoseEstimate& e, double off) noexcept {
  if (e.state != TrackState::kTracking || !(cfg.max_false_probability > 0) || loss.calibrating() || !fit_level.known())
    return;
  const double s = std::clamp(static_cast<double>(e.score), 0.0, 1.0);
  if (!(e.chi2 > 0) || s >= 1) return;
  const double floor_sd = fit_floor_sd(s);
  if (!fit_level.significantly_above(e.chi2, significance_z(), floor_sd)) return;
  fit_in_excess = true;
  const double target_sq = 1.0 - fit_level.chi2() * (1.0 - s * s) / e.chi2;  // s_t²
  if (!(target_sq > 0) || s * s >= target_sq * off * off) return;
  e.state = TrackState::kUncertain;
  e.reason_bits |= kReasonUnexplained;
}

// A TRACKING pose whose σ of scale lies above the target's own level (scale_sigma_level) both
// significantly (significance_z() SDs of the level's spread) and materially (kScaleSigmaJump
// times it): UNCERTAIN, kReasonUnexplained. Another object entering the window pulls the scale
// before it pulls the place: a twin coming down at 45° onto the procedural lamella (20 e-/px,
// pose_envelope_probe twin_crosses_down_at_45deg) drew the scale 1.00 -> 1.13 over ~25 frames
// while its σ grew from the target's 0.005 to 0.010-0.022 (σx only 0.25 -> 0.45-0.9 px), and 9
// poses 3-7.8 px off were TRACKING at scores and χ² near the target's level (now 1). Before any
// widening for blur (blur_level's job) and at the dwell's √ (a governor's step is no change of
// fit). The factor 2.5: the probe's 740 rows 86 -> 76 false TRACKING for 119 TRACKING frames
// (0.25 %), `--quick` identical; at 2.0, 74 false for 370 frames, and 9 fewer on `--quick`. In
// the --quick trace σ of scale exceeds 2.5x its stream's running median on 3 TRACKING poses of 5175.
void Tracker::Impl::judge_scale_sigma(PoseEstimate& e) noexcept {
  if (e.state != TrackState::kTracking || !(cfg.max_false_probability > 0) || loss.calibrating() || !(frame_scale_sigma > 0))
    return;
  if (scale_sigma_level.excess_sds(frame_scale_sigma, 0.0) <= significance_z() ||
      scale_sigma_level.excess(frame_scale_sigma) <= std::log(kScaleSigmaJump))
    return;
  e.state = TrackState::kUncertain;
  e.reason_bits |= kReasonUnexplained;
}

// A tracked scale away from the reference (kScaleDriftCheck: the search's scale, or one a frame
// showed clearly since) must show in the frame, or the pose it was measured at is not vouched for.
// Static structure under the pattern that the frames do not have (the pattern recorded over one
// patch of background, the target now over another) pulls the scale and the place together along
// the valley where they trade off: the procedural lamella at 20 e-/px, its pattern recorded over
// another seed's background, drifted 1.00 -> 1.05-1.15 within ~10 frames while its place ran 3-8 px
// off, TRACKING on σ 0.3-0.8 px and χ² at its own level (pose_false_tracking_test
// PatternRecordedOverAnotherBackground: 5 false over 4 runs of 150 frames; with the background's
// contrast 0.2, 57). The frame is asked what the start search asks of a scale away from the
// expected one (ScaleEvidenceCheck), with the pattern at the reference scale moved to its own best
// place (kDriftPlaceSteps 1 px steps, then ½ px): clear evidence makes the scale the reference.
// Short of that a TRACKING pose is UNCERTAIN (kReasonUnexplained) when both
//  - the frame does not show the target's loss at the reference scale a rigid target would
//    (kDriftShare of it, within kDriftZ SDs of the gain's noise): on those drifts 0.1-0.35, on the
//    scale ramps of the benchmark 0.27-0.77 (2.5 e-/px; the search's bar of 0.5 and 4 SDs made the
//    procedural lamella's ±25 % ramps at 2.5 e-/px 92 -> 65-68 % TRACKING);
//  - the two scales put the target more than kDriftPlacePx apart: the pose depends on which scale
//    is right. Every drifted pose ≥ 1.5 px off above had its two places > 1 px apart; the gripper
//    whose opening jaws drew the scale to 1.10 kept its body's place at either (0.24 px off).
// Places more than a false pose's 3 px apart need the clear evidence (at contrast 0.2 drifts to
// 1.18-1.21 with places 4-5 px apart passed the 0.35 bar at 0.30-0.36: 17 -> 11).
// Measured: the case above 5 -> 0 false (20 e-/px), 57 -> 11 at contrast 0.2; pose_accuracy_bench
// --quick 0 false either way, TRACKING 5175 -> 5171 of 5580 frames.
void Tracker::Impl::judge_scale_drift(const PatternBank& bank, const Measurement& m, double used_scale,
                                      PoseEstimate& e) noexcept {
  if (std::fabs(used_scale / scale_reference - 1.0) <= kScaleDriftCheck) return;
  // In the loaded ROI (resampled by 1 / used_scale) the pose's own scale is a factor 1.
  const double ref_factor = scale_reference / used_scale, window = std::min(ref_factor, 1.0);
  Measurement at_ref = m;
  double best = scale_probe.score(bank, at_ref, ref_factor, window);
  for (double step : {1.0, 0.5}) {
    for (int k = 0; k < kDriftPlaceSteps; ++k) {
      Measurement next = at_ref;
      bool moved = false;
      for (const auto& [sx, sy] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
        Measurement t = at_ref;
        t.dx += sx * step;
        t.dy += sy * step;
        const double r = scale_probe.score(bank, t, ref_factor, window);
        if (r > best) {
          best = r;
          next = t;
          moved = true;
        }
      }
      if (!moved) break;
      at_ref = next;
    }
  }
  const ScaleEvidence ev = scale_evidence.compare(bank, m, 1.0, at_ref, ref_factor);
  if (!ev.valid) return;
  if (ev.clear) {
    scale_reference = used_scale;
    return;
  }
  const double gain = ev.r_away - ev.r_expected;
  const double place_shift_px = used_scale * std::hypot(at_ref.dx - m.dx, at_ref.dy - m.dy);
  // Two places farther apart than a false pose's bound: taking the wrong one is a false pose, so
  // only the clear evidence above vouches for the tracked scale.
  const bool shown = place_shift_px <= LossPolicy::kFalsePx &&
                     gain + kDriftZ * ev.noise >= kDriftShare * ev.r_away * (1.0 - ev.rho);
  if (shown || place_shift_px <= kDriftPlacePx || e.state != TrackState::kTracking) return;
  e.state = TrackState::kUncertain;
  e.reason_bits |= kReasonUnexplained;
}

// After a loss, a search's re-find (refind_level, opened at the search frame): TRACKING only once
// a pose reaches the share of the attainable score the target reached before it, less
// kRefindShare (tracker_impl.hpp says why). No lapse: a target whose look changed while lost is
// followed, UNCERTAIN, until it explains its window again, or a REACQUIRE or SELECT forgets the
// level (an operator's word that this is the target).
void Tracker::Impl::check_refind_level(PoseEstimate& e) noexcept {
  if (!(refind_level > 0)) return;
  if (frame_explained > 0 && frame_explained >= refind_level - kRefindShare) {
    refind_level = 0;
    return;
  }
  if (++refind_below_frames >= kRefindSearchEvery) {
    refind_below_frames = 0;
    refind_research = true;
  }
  if (e.state != TrackState::kTracking || !(cfg.max_false_probability > 0)) return;
  e.state = TrackState::kUncertain;
  e.reason_bits |= kReasonUnexplained;
}

// After a loss on a tear (tear_level): TRACKING only at the level the target kept before it.
void Tracker::Impl::check_tear_level(const Measurement& m, PoseEstimate& e) noexcept {
  if (!(tear_level > 0) || e.state != TrackState::kTracking || !(cfg.max_false_probability > 0)) return;
  if (m.score >= tear_level - tear_margin || ++tear_below_frames >= kTearLapseFrames) {
    tear_level = 0;
    return;
  }
  e.state = TrackState::kUncertain;
  e.reason_bits |= kReasonUnexplained;
}

// A held frame (the target there, its pose not vouched for) opens the continuity check: the
// followed poses after it are TRACKING again only once they lie where the last TRACKING poses'
// motion leads (continuity_anchor.hpp). Until then UNCERTAIN, kReasonUnexplained. A full-field
// search that found the target starts it afresh (its pose is judged by the search's own checks).
void Tracker::Impl::keep_continuity(const PoseFrame& frame, PoseEstimate& e) noexcept {
  const double t_s = 0.5e-9 * (static_cast<double>(frame.t_scan_start_ns) + static_cast<double>(frame.t_scan_end_ns));
  // A search that found nothing while another target of a look-alike set held a place it skipped
  // (held_by_others) keeps the line: two tracked needle tips of one pattern crossing at 90° were
  // both lost in the overlap, the searches of one found nothing for 5 frames while the other sat on
  // the merged image, forgot its line, then took the other's needle, TRACKING to the end
  // (rival_on_line). Alone, a target whose searches find nothing forgets it as before (one that
  // left the field and came back on another line).
  const bool found = e.state == TrackState::kTracking || e.state == TrackState::kUncertain;
  if (e.searched && !line_rival && (found || frame.held_by_others.count == 0)) anchor.forget_keeping_velocity(found_after_hold);
  if (held_frames > 0 || (e.searched && line_rival)) anchor.doubt();
  // A declined jump (check_motion): a second object at the target's level beside it, which may
  // cover it next; the poses after it must keep to the line as after a held frame, and this one
  // (UNCERTAIN) does not count as keeping to it.
  if (jump_declined) anchor.contested();
  // A search that found the target on the line's place measured its size (it covers the scale
  // levels around the last): the line's size is that one (ContinuityAnchor::resized).
  ContinuityAnchor::Line line;
  if (e.searched && found && anchor.line_at(t_s, line) && std::hypot(e.x_px - line.x_px, e.y_px - line.y_px) <= line.tol_px)
    anchor.resized(e.scale);
  const bool followed = tracking && (e.state == TrackState::kTracking || e.state == TrackState::kUncertain);
  bool off_line = false;
  if (anchor.open() && followed && !jump_declined && !anchor.confirm(t_s, e.x_px, e.y_px, e.phi_deg, e.scale, e.sigma_scale)) {
    if (e.state == TrackState::kTracking) {
      e.state = TrackState::kUncertain;
      e.reason_bits |= kReasonUnexplained;
    }
    off_line = anchor.line_at(t_s, line) && std::hypot(e.x_px - line.x_px, e.y_px - line.y_px) > line.tol_px + ContinuityAnchor::kFalsePx &&
               line.x_px >= 0 && line.y_px >= 0 && line.x_px <= field.field_w - 1 && line.y_px <= field.field_h - 1;
  }
  // Followed clearly off the line (beyond its tolerance by kFalsePx) for kBackToLineFrames in a
  // row while its check is open: the followed pose is another object that took the window (a
  // twin that covered the target and moved on), never vouched for, while the line's place is
  // where the target is. The next ROI goes back there (a fresh start of the motion at the line's
  // place); the check stays open, so the target's poses there are TRACKING only once
  // kConfirmFrames of them keep to the line. Before, the needle tip crossed by a twin at 90° at
  // 6 e-/px (pose_envelope_probe twin_crosses_over_at_90deg), held, then taken 37 px off by the
  // walk onto the twin, was followed UNCERTAIN for 50 frames until the twin left the field; the
  // probe's twin rows: the lamella on post passing twins 59 -> 79 % TRACKING.
  off_line_frames = off_line ? off_line_frames + 1 : 0;
  if (off_line_frames >= kBackToLineFrames) {
    motion.accept(line.x_px, line.y_px, line.phi_deg, true);
    off_line_frames = 0;
  }
  // After a search that forgot the line: vouched for only while the poses keep its velocity
  // (ContinuityAnchor::forget_keeping_velocity).
  if (anchor.on_probation() && followed && !anchor.keeps_velocity(t_s, e.x_px, e.y_px, field.field_w, field.field_h) && e.state == TrackState::kTracking) {
    e.state = TrackState::kUncertain;
    e.reason_bits |= kReasonUnexplained;
  }
  // The line is drawn through poses the pattern explains: a TRACKING pose whose fit is
  // significantly worse than the target's level (not by enough for judge_fit to doubt it) may be
  // dragged by another object in its window. A twin crossing the lamella on post at 90°
  // (pose_envelope_probe twin_crosses_over_at_90deg, 6 e-/px) pulled its last TRACKING poses up
  // 1-5 px a frame at χ² 3.7 where the target reads ~2.1: the line's velocity, which a search
  // keeps (forget_keeping_velocity), turned from (1.06, -0.15) to (0.24, -1.30) px a frame, as
  // near the twin's (0, -3) as the target's own, and the needle tip crossed the same way kept a
  // line the drag had bent and stayed UNCERTAIN to the end after the twin left (35 % TRACKING at
  // 20 and 6 e-/px; now 73 %). Cost: a line gone stale on a target slowing down beside another
  // object, whose fit is in excess there, holds it UNCERTAIN longer after a hold
  // (target_moves_to_other_object_90px, the procedural lamella at 6 e-/px, 90 -> 70 %).
  // A pose after one the rules doubted whose fit is significantly worse than the target's level
  // (judge_fit's first test, its second not met) is TRACKING only where the line puts the target:
  // the material test forgives a stream vouched for up to this frame (those fast-scan poses
  // continued TRACKING streams), not one whose last pose was already doubted. A twin passing
  // below the lamella on its post (6 e-/px, pose_envelope_probe twin_passes_70px and
  // twin_crosses_over_at_90deg) drew the pose off over 2-4 UNCERTAIN frames, then poses 12-15 px
  // off at χ² 3.7-4.5 (the level 2.2-2.5, 3.7-4.5 SDs above it) kept 0.86 of the score the target
  // reaches there, more than the 0.83 a pose 3 px off keeps: TRACKING. Another object near a
  // target that keeps to its line raises its χ² as much (the procedural lamella with an object 90 px
  // away at 20 e-/px: shares 0.83-0.93 either way); there the line vouches, as it does after a hold.
  if (fit_in_excess && !last_reported_tracking && e.state == TrackState::kTracking && anchor.line_at(t_s, line) &&
      std::hypot(e.x_px - line.x_px, e.y_px - line.y_px) > ContinuityAnchor::kFalsePx) {
    e.state = TrackState::kUncertain;
    e.reason_bits |= kReasonUnexplained;
  }
  if (e.state == TrackState::kTracking && !fit_in_excess) anchor.trusted(t_s, e.x_px, e.y_px, e.phi_deg, e.score, e.scale, e.sigma_scale);
}

// A twin of the pattern passing over the target covers it, the target is lost, and the search
// after the loss finds the merged image or the twin (pose_envelope_probe twin_passes_over_fast:
// the lamella on post re-found 14 px off on the twin, the poses then followed the twin out of
// the field, TRACKING up to 266 px off, since the search forgot the line). Nothing in the winner
// tells it from the target; the line does: the winner lies off where the last TRACKING poses
// put the target, so that place is measured too (the ROI there, at the found scale and the last
// tracked angle, the peak within the line's tolerance, the walk). A hypothesis there that scores
// with the winner (not below it by significance_z() SDs of a difference of two scores), or one the
// search itself would take as found (LossPolicy::found: a second object there, however the other
// one's body in its window lowers its score: the needle tips of keep_continuity, its own needle at
// 0.540 where the other one scored 0.626; its attainable score is not measured there), or, for a
// target covered before the loss (held, then lost), one above the score noise reaches anywhere in
// the field (LossPolicy::field_floor), makes the winner a rival: UNCERTAIN, and the line stays to
// judge the poses after it. The floor: a twin's shaft
// over the needle tip's window lost it, and the search took the twin's clean tip 20-50 px off,
// TRACKING, while the line's place held the target's own maximum at 0.46-0.54 (winner 0.68-0.78,
// field floor 0.30-0.34; pose_envelope_probe twin_crosses_down_at_45deg at 2.5 / 6 e-/px); noise
// does not reach that, a background with a look-alike part the search would have weighed. And
// where the walk from the line's place climbs to a winner within the pattern's radius (the two
// merged: twin_passes_over at 6 e-/px, the winner 20 px off, the line's place on its slope at
// 0.56 binned), the same floor on the binned peak there: no maximum of its own, but more of the
// target's score than noise leaves. Not a veto: a line whose place holds nothing of the target's
// score (it left, jumped, turned) lets the winner be judged as before. RT: one ROI load, one
// binned FFT and a walk, on such search frames only.
bool Tracker::Impl::rival_on_line(const PatternBank& bank, const std::uint16_t* px, const Roi& field_roi, int bits,
                                  const PoseEstimate& e, const AnglePrior& last, double t_s) noexcept {
  ContinuityAnchor::Line line;
  if (!(cfg.max_false_probability > 0) || loss.calibrating() || !last.known || !anchor.line_at(t_s, line)) return false;
  const double lx = line.x_px, ly = line.y_px, tol = line.tol_px;
  const int pattern_px = sizes.pattern_px;
  // A line too old to say where the target is (its tolerance a look-alike's distance) is forgotten.
  if (tol > pattern_px / 4.0) return false;
  // On the line: the target, or a twin still merged with it (twin_passes_over_fast at 2.5 e-/px:
  // found 6 px off between the two, TRACKING, then the poses followed the twin out). A line that
  // held frames had opened stays open: the poses after the search must keep to it.
  if (std::hypot(e.x_px - lx, e.y_px - ly) <= tol) return anchor.open();
  const double fx = lx + lag_shift_px - field_roi.x, fy = ly - field_roi.y;  // the line's place in this frame's pixels
  const FieldCut cut = load_field_cut(px, field_roi, bits, fx, fy, e.scale);
  if (!cut.valid) return false;
  const double c = (pattern_px - 1) / 2.0;
  const double ux = cut.loaded_x(fx) - c, uy = cut.loaded_y(fy) - c;  // the line's pattern top-left, loaded
  const double r_b = tol / cut.used_scale / 2.0 + 1.0;  // binned px
  const SearchWindow win{static_cast<int>(std::floor(ux / 2.0 - r_b)), static_cast<int>(std::floor(uy / 2.0 - r_b)),
                         static_cast<int>(std::ceil(ux / 2.0 + r_b)), static_cast<int>(std::ceil(uy / 2.0 + r_b))};
  const int j = angles.index_of(last.phi_deg);
  half.correlate(bank.spectrum(j), maps.work());
  const Peak on_line = find_peak(maps.work(), half.valid_w(), half.valid_h(), win);
  const Measurement r = walk.measure(bank, j, on_line, cfg.max_angle_steps_per_frame);
  if (!r.valid) return false;
  // Only for a target covered before the loss (held, then lost): a glitched or jumping frame
  // loses it at once, and its line, kept, would hold the poses after it UNCERTAIN on a path that
  // has curved away from the line (half_shifted_20px, the needle tip at 20 e-/px: 87 -> 49 %).
  const auto above_noise = [&](double score) { return lost_after_hold && loss.field_floor() > 0 && score > loss.field_floor(); };
  // Still on the line after the walk (it may climb to the winner's own maximum).
  const double rx = cut.frame_x(r.ux + r.dx + c) - fx, ry = cut.frame_y(r.uy + r.dy + c) - fy;
  if (std::hypot(rx, ry) > tol) return above_noise(on_line.score) && std::hypot(e.x_px - lx, e.y_px - ly) < 0.5 * pattern_px * e.scale;
  return static_cast<double>(r.score) >= e.score - significance_z() * flip_sd(e.score) || loss.found(r, 0.0) || above_noise(r.score);
}

// A re-acquisition after a loss that came through held frames. Held, the target was at its
// place and scored there, only not as its pattern (another object drawn over its rim, jaws
// open): covered or changed, not gone — a jump leaves its ROI with nothing of the target and is
// lost at once. A search's winner beyond the pattern's radius from that place is then another
// object's part that resembles the pattern as well as the covered target does, or the target
// carried away: pose_envelope_probe other_object_comes_to_60px, the needle tip under the lamella
// on post at 2.5 e⁻/px, held 8 frames at its place, the search took the lamella's edge 74 px away
// at 0.686 where the needle's level was 0.725 (within the confirmed margin) and the poses followed
// it, TRACKING 60-105 px off on 55 frames; target_moves_to_other_object_60px, the needle at
// 20 e⁻/px, 88 px away at 0.67 (level 0.91), TRACKING once the edge scored like a pose 3 px off,
// 12 poses up to 140 px off. No single frame tells them from the target: the poses after such a
// search are UNCERTAIN (kReasonUnexplained) until the mean of their last kAwaySettleFrames log χ²
// is within its noise and kAwayOffsetSpreads of one frame's spread of the target's fit level
// (fit_level.hpp, kept through the loss): the edge fits worse than the needle did (20 e⁻/px: χ²
// 9-16 against 4.3; at 2.5 e⁻/px 1.7-2.4 against 1.54, a mean log excess of 0.31 where one frame's
// spread is 0.07). Not its place: the edge stopped 60 px from the needle's, within the pattern's
// radius. The cost: a true target re-found away from where it was held (back from a corner of
// the field, out from under a twin) waits those 8 frames UNCERTAIN.
bool Tracker::Impl::off_held_place(const PoseEstimate& e) const noexcept {
  if (!(cfg.max_false_probability > 0) || loss.calibrating()) return false;
  return std::hypot(e.x_px - held_x_px, e.y_px - held_y_px) > 0.5 * sizes.pattern_px * held_scale;
}

void Tracker::Impl::judge_away_from_held(PoseEstimate& e) noexcept {
  if (e.state != TrackState::kTracking && e.state != TrackState::kUncertain) return;
  if (fit_level.known() && e.chi2 > 0) {
    const double s = std::clamp(static_cast<double>(e.score), 0.0, 1.0);
    const double floor_sd = fit_floor_sd(s);
    // The last kAwaySettleFrames frames' excesses (a ring): a re-found target's level there may sit
    // a little off the old one for good, which a mean over every frame since would hold against it
    // ever more tightly.
    const double x = fit_level.excess(e.chi2);
    const int slot = away_frames % kAwaySettleFrames;
    away_excess_sum += x - (away_frames >= kAwaySettleFrames ? away_excess[slot] : 0.0);
    away_excess[slot] = x;
    ++away_frames;
    const double spread = fit_level.spread(floor_sd);
    const double allowed = kAwayOffsetSpreads * spread + significance_z() * spread / std::sqrt(static_cast<double>(kAwaySettleFrames));
    if (away_frames >= kAwaySettleFrames && away_excess_sum / kAwaySettleFrames <= allowed) {
      away_from_held = false;
      return;
    }
  }
  if (e.state == TrackState::kTracking) {
    e.state = TrackState::kUncertain;
    e.reason_bits |= kReasonUnexplained;
  }
}

// A re-acquisition off the line, turned by more than ContinuityAnchor::kTurnedDeg from the
// line's angle, and scoring below the level the line was tracked at (pose_envelope_probe
// twin_crosses_over_at_45deg: the lamella on post covered by a twin crossing at 45° was re-found
// 78 px off on a turned look-alike of the merged image, 0.83 where the line scored 0.93, then
// followed onto the target's own 180° look-alike 15 px off: TRACKING 180° off on 108 of 180
// frames). A target does not turn 180° while lost (the search's own tie-break), and one re-found
// after a jump scores at its level; a twin's merged image does not. Turned by the evidence, not
// a tie: the winner leads its opposite by significance_z() SDs (a near-symmetric target's turned
// copy is its flip check's business). Below the level by the confirmed margin (kConfirmShare of
// the room 1 − level²) and the noise of a score difference. The line is kept: UNCERTAIN until a
// pose keeps to it, place and angle.
bool Tracker::Impl::turned_off_line(const Measurement& m, const PoseEstimate& e, double t_s) const noexcept {
  ContinuityAnchor::Line line;
  if (!(cfg.max_false_probability > 0) || loss.calibrating() || !anchor.line_at(t_s, line)) return false;
  if (line.tol_px > sizes.pattern_px / 4.0 || std::hypot(e.x_px - line.x_px, e.y_px - line.y_px) <= line.tol_px ||
      !ContinuityAnchor::turned(e.phi_deg, line))
    return false;
  const double z = significance_z();
  if (!(m.flip_score >= -1.0f) || m.score - m.flip_score < z * flip_sd(m.score)) return false;
  const double level = line.score;
  return e.score < level - std::max(LossPolicy::kConfirmShare * (1.0 - level * level), z * flip_sd(level));
}

// ---------------------------------------------------------------------------------------

Tracker::Tracker(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Tracker::~Tracker() = default;

Roi Tracker::next_roi() const noexcept {
  const Impl& t = *impl_;
  const int field_w = t.field.field_w, field_h = t.field.field_h;
  if ((!t.tracking && t.held_frames == 0) || t.reacquire.load(std::memory_order_relaxed)) return {0, 0, field_w, field_h};
  return t.motion.window_at_prediction(std::min(t.sizes.roi_px, field_w), std::min(t.sizes.roi_px, field_h), field_w,
                                       field_h);
}

// The time the beam passed the pose's row (PoseEstimate::t_beam_ns): a raster scan's rows take
// equal shares of its time (flyback included), the pixel's place along its row is below one
// row's time and left out.
static std::int64_t beam_time_ns(const PoseFrame& frame, const PoseEstimate& e) noexcept {
  const std::int64_t span = frame.t_scan_end_ns - frame.t_scan_start_ns;
  if (frame.t_scan_start_ns == 0 || span <= 0) return 0;
  const bool measured = e.state == TrackState::kTracking || e.state == TrackState::kUncertain;
  const double share = measured && frame.roi.h > 0 && std::isfinite(e.meas_y_px)
                           ? std::clamp((e.meas_y_px - frame.roi.y + 0.5) / frame.roi.h, 0.0, 1.0)
                           : 0.5;
  return frame.t_scan_start_ns + static_cast<std::int64_t>(std::llround(share * static_cast<double>(span)));
}

PoseEstimate Tracker::update(const PoseFrame& frame) noexcept {
  PoseEstimate e = impl_->update(frame);
  // The reported pose is the filtered one when tracker.filter is on: the states judge the
  // measurement, so a filtered pose far from it is not vouched for (accept() restarts the filter
  // beyond the false-pose distance).
  if (e.state == TrackState::kTracking && (std::hypot(e.x_px - e.meas_x_px, e.y_px - e.meas_y_px) > 0.5 * LossPolicy::kFalsePx ||
                                           std::fabs(rt::wrap_deg(e.phi_deg - e.meas_phi_deg)) > 0.5 * LossPolicy::kFalseDeg)) {
    e.state = TrackState::kUncertain;
    e.reason_bits |= kReasonUnexplained;
  }
  impl_->keep_continuity(frame, e);
  if (e.state == TrackState::kTracking) impl_->ever_tracking = true;
  impl_->last_reported_tracking = e.state == TrackState::kTracking;
  e.followed = impl_->tracking && (e.state == TrackState::kTracking || e.state == TrackState::kUncertain);
  e.t_beam_ns = beam_time_ns(frame, e);
  if (e.followed && e.t_beam_ns > 0) impl_->recent.note(1e-9 * static_cast<double>(e.t_beam_ns), e.x_px, e.y_px, e.phi_deg);
  // The scan's motion bias comes out of the reported pose only, after every rule judged the pose
  // as measured: the rules (continuity line, stillness, split and flip checks) were measured on
  // uncorrected poses, and a correction that follows a velocity a twin or a glitch bent moved
  // their inputs (pose_envelope_probe 69 -> 96 false with it inside them; pose README, Motion
  // during the scan). The next ROI and the motion model keep the measured pose too.
  if (e.state == TrackState::kTracking || e.state == TrackState::kUncertain) impl_->unskew(e);
  return e;
}

void Tracker::set_start_area(double x_px, double y_px, double radius_px) noexcept {
  impl_->start_x = x_px;
  impl_->start_y = y_px;
  impl_->start_r = radius_px > 0 && std::isfinite(radius_px) ? radius_px : 0.0;
}

bool Tracker::selectable(std::uint8_t set, double nm_per_px) const noexcept {
  const Impl& t = *impl_;
  if (set >= t.banks.size()) return false;
  if (!(nm_per_px > 0 && std::isfinite(nm_per_px) && t.nm_per_px[set] > 0)) return true;  // not told: scale 1
  const double expected = t.nm_per_px[set] / nm_per_px;
  constexpr double kRounding = 1e-9;  // a told nm/px at the range's end computed back from it
  return expected >= Impl::kScaleMin * (1 - kRounding) && expected <= Impl::kScaleMax * (1 + kRounding);
}

bool Tracker::select_pattern_set(std::uint8_t set, double nm_per_px) noexcept {
  Impl& t = *impl_;
  if (!selectable(set, nm_per_px)) return false;
  const bool told = nm_per_px > 0 && std::isfinite(nm_per_px) && t.nm_per_px[set] > 0;
  const double expected = told ? std::clamp(t.nm_per_px[set] / nm_per_px, Impl::kScaleMin, Impl::kScaleMax) : 1.0;
  // Being told the size already assumed is no new look: it only narrows the next search.
  t.scale_told.store(told, std::memory_order_relaxed);
  const bool new_size = std::fabs(t.expected_scale.exchange(expected, std::memory_order_relaxed) - expected) > 1e-3;
  if (t.active.exchange(set, std::memory_order_relaxed) != set || new_size) {
    // A new magnification changes the target's size on screen: find it again.
    t.reacquire_commanded.store(true, std::memory_order_relaxed);
    t.reacquire.store(true, std::memory_order_relaxed);
  }
  return true;
}

std::size_t Tracker::pattern_set_count() const noexcept { return impl_->banks.size(); }
float Tracker::noise_floor_roi(std::size_t set) const noexcept {
  return set < impl_->noise_floors.size() ? impl_->noise_floors[set].roi : -1.0f;
}
float Tracker::noise_floor_field(std::size_t set) const noexcept {
  return set < impl_->noise_floors.size() ? impl_->noise_floors[set].field : -1.0f;
}
std::uint8_t Tracker::pattern_set() const noexcept { return impl_->active.load(std::memory_order_relaxed); }
PatternSymmetry Tracker::symmetry(std::size_t set) const noexcept {
  return set < impl_->symmetry.size() ? impl_->symmetry[set] : PatternSymmetry{};
}
double Tracker::nm_per_px() const noexcept { return impl_->nm_per_px[impl_->active.load(std::memory_order_relaxed)]; }
void Tracker::request_reacquire(bool commanded) noexcept {
  // Sticky: a command and sempose's own request before the same frame still mark it.
  if (commanded) impl_->reacquire_commanded.store(true, std::memory_order_relaxed);
  impl_->reacquire.store(true, std::memory_order_relaxed);
}

std::uint32_t Tracker::shortest_correctable_dwell_ns() const noexcept {
  return impl_->correctable_dwell_floor_ns.load(std::memory_order_relaxed);
}

Tracker::DetectorTauStatus Tracker::detector_tau_status() const noexcept {
  const Impl& t = *impl_;
  DetectorTauStatus s{t.measure_tau || t.check_told_tau, t.measured_rho.load(std::memory_order_relaxed),
                      t.measured_tau_px.load(std::memory_order_relaxed), t.measured_tau_ns.load(std::memory_order_relaxed),
                      t.measured_tau_frames.load(std::memory_order_relaxed)};
  s.told_tau_ns = t.cfg.detector_tau_ns > 0 ? t.cfg.detector_tau_ns : 0.0;
  s.frames_disagree = t.frames_disagree_status.load(std::memory_order_relaxed);
  s.frames_lag_measured = t.frames_lag_measured.load(std::memory_order_relaxed);
  s.lag2_excess = t.measured_lag2_excess.load(std::memory_order_relaxed);
  s.inconsistent = t.measured_inconsistent.load(std::memory_order_relaxed);
  s.patterns_told_overruled = t.patterns_overruled;
  s.beyond_frames = t.lag_beyond_frames.load(std::memory_order_relaxed);
  s.beyond_max_px = t.lag_beyond_max_px.load(std::memory_order_relaxed);
  return s;
}

std::size_t Tracker::memory_bytes() const noexcept {
  const Impl& t = *impl_;
  std::size_t b = t.half.buffer_bytes() + t.coarse.buffer_bytes() + (t.coarse_wide ? t.coarse_wide->buffer_bytes() : 0);
  b += t.scorer.memory_bytes() + t.loader.memory_bytes() + t.rescaler.memory_bytes() + t.maps.memory_bytes() +
       t.search.memory_bytes();
  for (const auto& bank : t.banks) b += bank->memory_bytes();
  // A learned bank shares the spectra and holds its own full-resolution copies (two slots).
  if (t.observer) {
    b += t.observer->memory_bytes();
    for (const auto& bank : t.banks) b += 2 * static_cast<std::size_t>(bank->angles()) * bank->size_px() * bank->size_px() * sizeof(float);
  }
  return b;
}

}  // namespace sempose::pose
