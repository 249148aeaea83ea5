// Private to the pose engine: the tracker's state, shared by the files that implement it —
// tracker.cpp (the per-frame sequence of stages), tracker_create.cpp (setup: validation,
// stage construction, noise-floor calibration) and tracker_appearance.cpp (learned-bank swaps).
#pragma once

#include "sempose/pose/tracker.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>
#include <thread>

#include "sempose/pose/angle_grid.hpp"
#include "sempose/pose/angle_sweep.hpp"
#include "sempose/pose/appearance_model.hpp"
#include "sempose/pose/appearance_observer.hpp"
#include "sempose/pose/continuity_anchor.hpp"
#include "sempose/pose/detector_lag.hpp"
#include "sempose/pose/fit_level.hpp"
#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/line_correlation.hpp"
#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/loss_policy.hpp"
#include "sempose/pose/motion_model.hpp"
#include "sempose/pose/orientation_walk.hpp"
#include "sempose/pose/pattern_bank.hpp"
#include "sempose/pose/pattern_symmetry.hpp"
#include "sempose/pose/pose_filter.hpp"
#include "sempose/pose/pose_refinement.hpp"
#include "sempose/pose/pose_uncertainty.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/recent_motion.hpp"
#include "sempose/pose/roi_loader.hpp"
#include "sempose/pose/roi_rescaler.hpp"
#include "sempose/pose/scale_probe.hpp"
#include "sempose/pose/scan_motion.hpp"
#include "sempose/pose/split_consistency.hpp"
#include "sempose/pose/stale_frame_check.hpp"
#include "sempose/pose/start_search.hpp"
#include "sempose/pose/subpixel_fit.hpp"
#include "sempose/rt/angle.hpp"

namespace sempose::pose {

// The outer ring of the pattern is made up at setup (prefilter edges replicated: 2 px per
// pass; bicubic rotation clamps its 2 px support at the square's edge): keep it out of the
// mask, or those pixels pull the peak off the true pose by a few tenths of a pixel in the
// pattern's own frame (a bias that turns with the target).
inline double mask_inset_px(const config::TrackerConfig& c) noexcept { return 2.0 + 2.0 * c.prefilter_passes; }

struct Tracker::Impl {
  // Setup: the stages, in the order a tracked frame meets them. Members are built in
  // declaration order; later stages keep references to earlier ones.
  const config::TrackerConfig cfg;
  // The one-sided normal quantile of tracker.max_false_probability (upper_normal_quantile):
  // how many SD make a difference significant at the rate a false pose is allowed. Read ~25
  // times a frame; the bisection behind it (50 erfc) was 1–2 % of a tracked frame (perf).
  const double significance_z_value;
  const EngineSizes sizes;
  const AngleGrid angles;
  const PatternMask fine_mask, half_mask, coarse_mask;
  FftCorrelator half, coarse;  // the 2×2-binned ROI level; the coarse full-field level (scanned size)
  // The coarse level of the search's levels below 1 (their enlarged frame), when it needs a
  // larger FFT than the scanned field's; null otherwise.
  std::unique_ptr<FftCorrelator> coarse_wide;
  ExactScorer scorer;
  RoiLoader loader;
  RoiRescaler rescaler;
  const ScaleProbe scale_probe;
  const ScaleEvidenceCheck scale_evidence;
  CorrelationMaps maps;
  const SubpixelFit fit;
  const OrientationWalk walk;
  AngleSweep sweep;
  StartSearch search;
  PoseRefinement refinement;
  SplitConsistencyCheck split;
  PoseUncertainty uncertainty;
  LossPolicy loss;
  MotionModel motion;
  PoseFilter filter;
  // A frame repeating the last one pixel for pixel is old light: held like a source-flagged bad
  // frame (stale_frame_check.hpp). Sized for the larger of the field and the ROI's FFT. At the
  // same place the repeat counts once the stream predicts a move of at least kStaleMovePx or
  // kStaleTurnDeg: below that a frozen frame leaves the pose as far behind as a still target's
  // noise-free frame would, and the noise-free still frames of a synthetic sequence are tracked.
  StaleFrameCheck stale;
  static constexpr double kStaleMovePx = 0.5, kStaleTurnDeg = 0.5;
  std::vector<std::unique_ptr<const PatternBank>> banks;
  std::vector<double> nm_per_px;
  // Per pattern set, the detector's lag along the line at the dwell it was recorded at, and
  // this frame's lag minus the active set's (px, taken out of every pose's x: tracker.cpp).
  std::vector<double> pattern_lag_px;
  double lag_shift_px = 0;
  // Per pattern set, how a target's motion during the scan biases its measured pose
  // (scan_motion.hpp), and this frame's velocity per scanned row (scan_velocity(), tracker.cpp):
  // the bias is taken out of the reported pose once the rules have judged the measured one
  // (Tracker::update).
  std::vector<ScanMotionResponse> scan_motion;
  const ScanMotionResponse* frame_scan_motion = nullptr;
  double row_vx_px = 0, row_vy_px = 0, row_turn_deg = 0;
  // τ not told (tracker.detector_tau_ns 0) and tracker.measure_detector_tau: measured from each
  // frame's noise, kept from the frames whose pose was accepted (accept()), and the lags taken
  // from it instead; the pattern sets' dwells for their own lag, or, a set without one, the
  // lag its own noise shows (measured at setup; 0 where it cannot be told). Published for the
  // status. A band of lines a frame (tau_band_line: where the next band starts), so no frame
  // pays for the whole read.
  bool measure_tau = false;
  // τ told and tracker.measure_detector_tau: the same readings check it. A pattern set whose
  // own noise disagrees with its told lag (DetectorTauEstimator::told_disagrees: a clean crop
  // given a dwell_ns, a recording through the detector given none) counts the lag its noise
  // shows (pattern_told_overruled, decided at setup). Frames whose readings disagree with τ at
  // their dwell (a detector swapped, a dwell changed without the config — or a scan fault the
  // gate lets through: every 4th line dropped reads ρ 0.73–0.79 at 20 e⁻/px) are reported
  // (frames_disagree, sticky) and, while the readings are a low-pass's (the lag-2 check), their
  // lag used in place of the told one (frames_lag_measured); dropped lines are not a low-pass's
  // and keep the told lag (used, their reading put 110 poses > 3 px off, README). Decided on the
  // kept estimate from kToldCheckFrames on.
  bool check_told_tau = false;
  bool frames_disagree = false;
  std::vector<char> pattern_told_overruled;
  std::atomic<bool> frames_disagree_status{false};
  std::atomic<bool> frames_lag_measured{false};
  int patterns_overruled = 0;
  DetectorTauEstimator tau_estimate;
  int tau_band_line = 0;
  std::vector<double> pattern_dwell_ns;
  std::vector<double> pattern_measured_rho;
  std::atomic<double> measured_rho{0}, measured_tau_px{0}, measured_tau_ns{0}, measured_tau_frames{0};
  std::atomic<double> measured_lag2_excess{0};
  std::atomic<bool> measured_inconsistent{false};
  std::atomic<double> lag_beyond_frames{0}, lag_beyond_max_px{0};
  // The shortest dwell whose lag against the active set's pattern stays within what sempose
  // corrects (Tracker::shortest_correctable_dwell_ns; 0: no detector lag known).
  std::atomic<std::uint32_t> correctable_dwell_floor_ns{0};
  void update_dwell_floor() noexcept;
  // The detector τ this frame's lag was taken at (lag_shift_of: told, measured, or measured in
  // place of a told one the frames contradict; 0 when no lag is known): the floor's τ.
  double frame_tau_ns = 0;
  // A TRACKING pose of a frame whose lag against the pattern is beyond kMaxCorrectedLagPx: UNCERTAIN.
  void judge_lag(PoseEstimate& e) noexcept;
  // The frames' lag told; the set's lag told or, overruled, its own.
  double told_checked_lag_shift(std::uint8_t set) noexcept;
  // This frame's lag against the active set's pattern (px along x), told or measured.
  double lag_shift_of(const PoseFrame& frame, std::uint8_t set) noexcept;

  bool tracking = false;
  // Held: the last frames were LOST only because the rigid pattern did not explain the window
  // (the target is there, its score at its level, but part of it moved: jaws). The ROI stays
  // on the target instead of a full-field search (77 ms of scan at 640×480, and the search
  // would not find a deformed target either) for at most kMaxHeldFrames; the poses are not
  // TRACKING until a frame passes every check again.
  int held_frames = 0;
  static constexpr double kImplausibleWider = 1.5;  // motion check: implausible beyond 1.5 × the surprise limits
  static constexpr int kMaxHeldFrames = 25;  // ~0.25 s of 192² ROIs, then the field is searched
  // The target's scale (size over the pattern's): each tracked ROI is resampled by 1/scale.
  // Learnt from the accepted frames' scale readings, kept across a loss (the magnification
  // has not changed), back to the expected scale when the target is forgotten (new pattern
  // set, REACQUIRE).
  double scale = 1.0;
  // What scale starts at before a search: 1, or the set's nm/px over a SELECT's (written by
  // select_pattern_set, possibly from another thread than update()).
  std::atomic<double> expected_scale{1.0};
  // Whether a SELECT gave the microscope's nm/px: then the start search looks near the
  // expected scale only (one level); else over tracker.search_scale_min…max times it.
  std::atomic<bool> scale_told{false};
  // `scale` was tracked (a search found the target since it was last forgotten): the
  // re-search after a loss covers the levels around it (StartSearch: ScalePrior).
  bool scale_tracked = false;
  // Searches in a row since the last one that found the target. After kScalePriorLapse of
  // them the re-search forgets the last tracked scale and looks around the expected one again
  // (tracker.cpp: the scale prior).
  int searches_rejected = 0;
  // The scale the target was last shown to have: the search's, or a tracked scale the frame
  // showed clearly better than it (judge_scale_drift).
  double scale_reference = 1.0;
  static constexpr double kScaleDriftCheck = 0.025;  // a tracked scale this far from it is checked
  static constexpr int kDriftPlaceSteps = 6;          // 1 px steps of the place at the reference scale (then ½ px)
  static constexpr double kDriftShare = 0.35, kDriftZ = 2.0, kDriftPlacePx = 1.0;  // judge_scale_drift
  static constexpr int kScalePriorLapse = 3;
  static constexpr double kScaleGain = 0.5;         // share of a frame's reading taken at once
  static constexpr double kScaleMin = kTrackedScaleMin, kScaleMax = kTrackedScaleMax;  // beyond: the ROI cannot hold the target
  // Closer to 1 than this: the raw ROI is loaded as scanned (RoiRescaler::kMinChange).
  static constexpr double kRescaleFrom = RoiRescaler::kMinChange;
  config::ScanLimits field;  // the scan field's size (from setup, then from the frames)
  std::atomic<bool> reacquire{false};
  // The config's start area (radius 0: none) and whether a pose was ever TRACKING (it then no
  // longer applies).
  double start_x = 0, start_y = 0, start_r = 0;
  bool ever_tracking = false;
  // The pending re-acquisition was commanded (REACQUIRE, SELECT): its search's pose is marked.
  std::atomic<bool> reacquire_commanded{false};
  std::atomic<std::uint8_t> active{0};

  // Learned appearance (only when tracker.appearance.enabled): the observer fills batches on
  // the RT side; maintain_appearance() (worker or offline caller) folds them into the model and
  // publishes a bank with the learned support into the free one of two slots per set.
  struct LearnedBanks {
    std::unique_ptr<const PatternBank> slot[2];
    float floor_scale[2] = {1.0f, 1.0f};  // noise floors grow as the support shrinks
    std::atomic<int> published{-1};       // -1: the recorded bank
    std::atomic<int> in_use{-1};          // what update() last picked up
  };
  std::unique_ptr<LearnedBanks[]> learned;
  std::unique_ptr<AppearanceObserver> observer;
  std::unique_ptr<AppearanceModel> model;
  bool learning = false;          // off while the noise floors are measured
  int bank_seen = -1;             // the slot update() used last (noise floors follow it)
  float floor_scale_now = 1.0f;
  std::atomic<std::uint32_t> appearance_accepted{0}, appearance_rejected{0}, appearance_deferred{0};
  std::atomic<double> appearance_support{1.0};
  std::atomic<std::uint32_t> appearance_template_updates{0};
  std::atomic<double> appearance_template_weight{0.0};
  std::thread worker;
  std::atomic<bool> worker_stop{false};
  std::atomic_flag maintaining = ATOMIC_FLAG_INIT;  // one maintain_appearance() at a time (non-RT callers)
  ~Impl() {
    worker_stop.store(true, std::memory_order_relaxed);
    if (worker.joinable()) worker.join();
  }
  const PatternBank& frame_bank(std::uint8_t set) noexcept;
  bool maintain_appearance();

  Impl(const config::TrackerConfig& c, const EngineSizes& s, int field_width, int field_height)
      : cfg(c),
        significance_z_value(upper_normal_quantile(c.max_false_probability)),
        sizes(s),
        angles{static_cast<int>(std::lround(360.0 / c.angle_step_deg)), c.angle_step_deg},
        fine_mask(s.pattern_px, c.circular_mask, 8, mask_inset_px(c)),
        half_mask(s.pattern_px / 2, c.circular_mask, 8, mask_inset_px(c) / 2),
        coarse_mask(s.coarse_pattern_px, c.circular_mask),
        half(s.half_fft_px, s.half_fft_px, half_mask),
        coarse(good_fft_size(s.coarse_scan_w), good_fft_size(s.coarse_scan_h), coarse_mask),
        coarse_wide(s.wide_coarse() ? std::make_unique<FftCorrelator>(good_fft_size(s.coarse_max_w),
                                                                      good_fft_size(s.coarse_max_h), coarse_mask)
                                    : nullptr),
        scorer(fine_mask, s.roi_fft_px),
        loader(c.prefilter_passes, s.roi_fft_px, scorer, half),
        rescaler(s.roi_fft_px),
        scale_probe(scorer),
        scale_evidence(scorer),
        maps(static_cast<std::size_t>(s.half_fft_px) * s.half_fft_px),
        fit(c.subpixel == "gaussian", c.fit_noise_correction, c.fit_background_plane),
        walk(scorer, fit, angles),
        sweep(half, walk, angles, maps),
        search(cfg, sizes, angles, coarse, coarse_wide.get(), half, loader, rescaler, scale_probe, scale_evidence, walk, sweep, maps),
        refinement(scorer, c.refine, angles.step_deg),
        split(scorer, 1.0),
        uncertainty(scorer, s.pattern_px, c.sigma_tile_px, c.sigma_calibration, c.sigma_floor_px, c.sigma_floor_deg,
                    c.sigma_noise_factor, c.sigma_angle_factor, angles.count, c.sigma_pattern_noise, c.sigma_scale_factor),
        loss(cfg),
        motion(c.predict_velocity, c.predict_rate_poses),
        filter(c.filter),
        stale(static_cast<std::size_t>(std::max(field_width, s.roi_fft_px)) * static_cast<std::size_t>(std::max(field_height, s.roi_fft_px))) {
    field.field_w = field_width;
    field.field_h = field_height;
  }

  // Noise floors per pattern set (LossPolicy): measured at setup by calibrate_noise_floors().
  struct NoiseFloor {
    float roi = -1.0f;    // tracking ROI path (walk + recovery sweep)
    float field = -1.0f;  // full-field start search
  };
  static constexpr int kNullTrials = 8;
  static constexpr double kNullSigmas = 5.0;  // Gumbel tail: ~1e-3 per frame above mean + 5 sd
  static constexpr int kNullFieldMax = 2048;  // the floor grows only as sqrt(ln area)
  std::vector<NoiseFloor> noise_floors;
  double prefilter_noise_gain = 1.0;  // Σk² of the 2-D prefilter kernel (white-noise variance kept)
  PrefilterNoiseGain prefilter_noise;  // the same for noise correlated along the line (attainable score)
  // Per pattern set, the recorded pattern's own share of signal in its score, √(S/(S+N')) on the
  // raw pattern with the noise PatternBank measured (N' through the prefilter, as the attainable
  // score reads a window): the ZNCC of two noisy copies of one signal is the product of each
  // copy's factor, so the attainable score is multiplied by it (1 when
  // tracker.attainable_pattern_noise is off). Setup: pattern_attainable_factor().
  std::vector<double> pattern_factor;
  double attainable_factor = 1.0;  // the active set's, set at each update()
  // The active set's bank when its pattern set has a shape mask (a user's, not a learned
  // support): the attainable score is then read over the mask's pixels at the match's angle
  // (a masked score explains only those). Null otherwise; set at each update().
  const PatternBank* masked_bank = nullptr;

  void use_noise_floors_of(std::uint8_t set) noexcept {
    if (set < noise_floors.size())
      loss.set_noise_floors(std::min(1.0f, noise_floors[set].roi * floor_scale_now),
                            std::min(1.0f, noise_floors[set].field * floor_scale_now));
  }
  double attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy, int j) const noexcept;
  void calibrate_noise_floors(const config::ScanLimits& limits);
  void forget_everything() noexcept;

  PoseEstimate update(const PoseFrame& frame) noexcept;
  Measurement track(const PatternBank& bank, bool& swept, std::uint8_t set, const RawRoi& raw) noexcept;
  bool rivals(const Measurement& a, const Measurement& b, double used_scale) const noexcept;
  template <class Place>
  void check_motion(const PatternBank& bank, Measurement& m, PoseEstimate& e, bool swept, double origin_x, double origin_y,
                    double scale, const Place& place) noexcept;
  void to_estimate(const Measurement& m, int origin_x, int origin_y, PoseEstimate& e) const noexcept;
  static void set_sigma(const PoseSigma& s, double used_scale, PoseEstimate& e) noexcept;
  // A pose measured in the frame's pixels, to where the target is: the detector's lag at this
  // frame's dwell against the pattern's taken out of x (lag_shift_px).
  void unlag(PoseEstimate& e) const noexcept {
    e.x_px -= lag_shift_px;
    e.meas_x_px = e.x_px;
  }
  // The target's velocity (and turn rate) per scanned row this frame (frame.t_scan_* give the row's
  // time), from the continuity trail's rates once the motion since the search is known; 0 before,
  // without time stamps, and beyond kScanTurnMaxDeg of turn over the target's rows.
  void scan_velocity(const PoseFrame& frame, const PatternBank& bank) noexcept;
  static constexpr double kScanTurnMaxDeg = 10.0;  // the turn while the target's rows are scanned
  void unskew(PoseEstimate& e) const noexcept {
    if (frame_scan_motion == nullptr || (row_vx_px == 0 && row_vy_px == 0 && row_turn_deg == 0)) return;
    const ScanMotionBias b = frame_scan_motion->bias(e.phi_deg, scale, row_vx_px, row_vy_px, row_turn_deg);
    // The reported pose and the measurement alike (tracker.filter keeps them apart).
    e.x_px -= b.x_px;
    e.y_px -= b.y_px;
    e.phi_deg = rt::wrap_deg(e.phi_deg - b.phi_deg);
    e.meas_x_px -= b.x_px;
    e.meas_y_px -= b.y_px;
    e.meas_phi_deg = rt::wrap_deg(e.meas_phi_deg - b.phi_deg);
  }
  // A start search's pose gets σ as an ROI frame's does: the ROI around it cut from the field,
  // loaded at the found scale, the fit's covariance at the search's pose (tracker.cpp). Returns
  // the measurement placed in that loaded ROI and the scale it was loaded at (valid: loaded).
  struct Loaded {
    bool valid = false;
    Measurement at;
    double used_scale = 1.0;
  };
  // The ROI the next frame would scan around a place (fx, fy) of a full-field frame (the frame's
  // pixels), cut from it and loaded at load_scale (resampled by 1/load_scale about its centre, as
  // an ROI frame is); valid: loaded (not flat, the field holds the ROI). Setup sized every buffer.
  struct FieldCut {
    bool valid = false;
    int x0 = 0, y0 = 0, w = 0, h = 0;
    double used_scale = 1.0;
    // A place of the frame in the loaded ROI's pixels (RoiRescaler::to_raw inverted), and back.
    double loaded_x(double fx) const noexcept { return (w - 1) / 2.0 + (fx - x0 - (w - 1) / 2.0) / used_scale; }
    double loaded_y(double fy) const noexcept { return (h - 1) / 2.0 + (fy - y0 - (h - 1) / 2.0) / used_scale; }
    double frame_x(double lx) const noexcept { return x0 + (w - 1) / 2.0 + (lx - (w - 1) / 2.0) * used_scale; }
    double frame_y(double ly) const noexcept { return y0 + (h - 1) / 2.0 + (ly - (h - 1) / 2.0) * used_scale; }
  };
  FieldCut load_field_cut(const std::uint16_t* px, const Roi& field_roi, int bits, double fx, double fy, double load_scale) noexcept;
  Loaded search_sigma(const PatternBank& bank, const Measurement& m, const std::uint16_t* px, const Roi& field_roi, int bits,
                      PoseEstimate& e) noexcept;
  void go_lost() noexcept;
  void hold() noexcept;
  // How far an accepted pose landed from a prediction made from two ROI poses (known: there was one).
  struct Innovation {
    bool known = false;
    double d_px = 0, d_deg = 0;
  };
  bool trusted_pose(const PoseEstimate& e, const Innovation& innov) const noexcept;
  // A new target's first pose (no pose noise learnt or carried): a single field scan nothing
  // has confirmed yet, reported UNCERTAIN (tracker.cpp).
  bool first_pose_unconfirmed() const noexcept;
  // A first start's pose before the stream's noise is known scoring below the level the search
  // set by more than the detector noise explains: not trusted on its own σ (tracker.cpp).
  bool fell_below_search_level(float score) const noexcept;
  // Static clutter in the pattern (tracker.cpp, fell_while_still): a score that fell from the
  // last accepted pose's by more than the confirmed margin and the detector noise while the pose
  // stood still (within the noise of its σ) opens a doubt, kept while the pose stands still and
  // the score stays below the level before the fall; its poses are followed, UNCERTAIN.
  bool fell_while_still(const PoseEstimate& e) noexcept;
  bool scored_below(double score, double level, double level_dwell_ns) const noexcept;
  bool parts_doubted(const Measurement& m, const PatternBank& bank, double used_scale, const PoseEstimate& e) noexcept;
  bool last_known = false;  // the last accepted pose (and its score) below are set
  double last_x = 0, last_y = 0, last_phi = 0, last_score = 0;
  bool still_doubt = false;  // a fall while still is open
  bool parts_doubt = false;  // parts of the window moved apart (parts_doubted); the level before it:
  double parts_level = 0, parts_dwell_ns = 0;
  struct LevelBefore {
    bool known = false;
    double score = 0, dwell_ns = 0;
  } parts_before;  // the last frame's score while no doubt was open
  double still_level = 0;    // the last accepted score before that fall
  double last_dwell_ns = 0, still_dwell_ns = 0;  // the dwells last_score and still_level were scanned at
  // The motion check's sweep found a second hypothesis more than the false-pose rule's 3 px /
  // 10° from the pose kept whose score is within the noise of the kept one's (the two differ
  // by less than significance_z() SDs of a difference of two independent scores, flip_sd):
  // the frame cannot tell which is the target (a torn frame: the target jumped mid-scan and
  // half the ROI shows it at each place). Followed, reported UNCERTAIN.
  bool rival_within_noise = false;
  // The motion check kept the hypothesis the motion predicts over a surprising one scoring better,
  // because the predicted place holds the target's level too (declines_jump): reported UNCERTAIN.
  bool jump_declined = false;
  bool declines_jump(const Measurement& m, const Measurement& r, double ux, double uy, double plausible_px,
                     double used_scale) const noexcept;
  // Where the last TRACKING poses put the target (continuity_anchor.hpp): after a held frame a
  // pose is TRACKING again only where that motion leads (a twin passing over drags the pose).
  ContinuityAnchor anchor;
  // The target's χ² level on frames it tracked well (fit_level.hpp): kept across a loss, since
  // a re-acquisition is where a pose the model fits worse than it fits this target was taken
  // (a 90°-turned hypothesis of the lamella on post half under a dark occluder, χ² 16-40 where
  // the target's frames read ~2); forgotten with the target (REACQUIRE, SELECT, a new size).
  FitLevel fit_level;
  // The share of the attainable score the target reaches (s / a: how much of its window's signal
  // the pattern explains, relative to what noise allows) on frames it tracked well, in a FitLevel
  // (the median of the last 32; sampled on every ROI frame until known, 8 frames, then with
  // fit_level). Kept across a loss and forgotten with the target, as fit_level. A search that
  // re-finds the target after a loss opens check_refind_level at that level (refind_level): its
  // poses are TRACKING only once one reaches it less kRefindShare. Another micrograph's needle a
  // lost needle tip was re-found on (hostile round 13, F2) reads 0.66-0.71 where the tip read
  // 0.90-0.92 (its χ² only 1.4x the tip's: the other window's lower contrast absorbs the score's
  // fall, which s / a does not), and was TRACKING 38 of 120 frames, also after the tip came back.
  // Only the level's median is used, with a fixed margin: its spread over 8 frames in a row is
  // too narrow to judge by (as fit_level's was: kFitSampleEvery). The margin: pose_accuracy_bench
  // --quick's rows read, median per row, 0.70-0.99, at most ~0.1 lower at 2.5 e-/px than at 20 on
  // the same target, and a re-find after a jump within 0.05 of the row's level. Judging every
  // TRACKING frame against the share, not only a re-find's, was measured (2026-12-06): the probe's
  // false poses 69 -> 68, its TRACKING 47,429 -> 47,318 (1 e-/px rows beside other objects),
  // --quick identical, F5's crossing needles unchanged, and ~8 us a frame: not landed.
  FitLevel explained_level;
  double refind_level = 0;     // the share a re-found target must reach (0: no check open)
  double frame_explained = 0;  // this frame's s / a (0: not measured)
  static constexpr double kRefindShare = 0.15;
  // Followed below it for this many ROI frames, the field is searched again: the target may have
  // come back (F2: the tip crossed the field twice while its pattern sat on the other needle).
  int refind_below_frames = 0;
  bool refind_research = false;  // set by check_refind_level: go_lost() once the frame is judged
  static constexpr int kRefindSearchEvery = 8;
  void check_refind_level(PoseEstimate& e) noexcept;
  // The target's blur on frames it tracked well: 1 / PoseSigma::sharpness (the copy's curvature
  // over the fit's on the frame), in a FitLevel (median and spread of its log, the last 32 frames
  // TRACKING with no reason and not themselves widened). A frame significantly blurrier than that
  // (defocus) flattens the fit by the ratio, which the pose's σ — the copy's curvature — does not
  // see: widen_for_blur multiplies σ by it (README: Uncertainty, *Sharpness*). Kept across a loss,
  // forgotten with the target, as fit_level.
  FitLevel blur_level;
  // The target's σ of scale on frames it tracked well (before any widening for blur, times
  // √dwell so that a governor's dwell step does not read as a change), in a FitLevel: a pose
  // whose scale the frame determines far worse than the target's frames did is one something
  // else in the window pulls (judge_scale_sigma). Kept and forgotten as fit_level.
  FitLevel scale_sigma_level;
  double frame_scale_sigma = 0;  // this frame's, as learnt (0: not measured)
  static constexpr double kScaleSigmaJump = 2.5;
  void judge_scale_sigma(PoseEstimate& e) noexcept;
  void judge_scale_drift(const PatternBank& bank, const Measurement& m, double used_scale, PoseEstimate& e) noexcept;
  double frame_blur = 0;  // this frame's 1 / sharpness (0: not measured)
  bool blur_widened = false;  // this frame's σ was widened: not learnt
  double blur_run = 0, blur_run_var = 1;  // the run's log blur and its variance in frames'
  bool blur_run_known = false;
  static constexpr double kBlurRunGain = 0.5;
  void widen_for_blur(const PoseSigma& s, PoseEstimate& e) noexcept;
  // The fit is worse than the target's level, significantly and by more than a pose off by the
  // false-pose radius would be (off_share, off_pose_score.hpp): UNCERTAIN, kReasonUnexplained.
  void judge_fit(PoseEstimate& e, double off) noexcept;
  // This frame's χ² lay significantly above the target's level (judge_fit's first test, whether
  // or not its second made the pose UNCERTAIN): the pose is not one the continuity line is drawn
  // through (keep_continuity says why).
  bool fit_in_excess = false;
  // The last pose reported was TRACKING (Tracker::update): a significant χ² that is not material
  // is forgiven off the continuity line only a stream vouched for up to this frame (keep_continuity).
  bool last_reported_tracking = false;
  // The detector noise's share of one frame's log χ² SD at score s (FitLevel's floor_sd):
  // log(1 − s²) moves by 2s/√N_eff, and log(1 − a²) as much again.
  double fit_floor_sd(double s) const noexcept { return 2.0 * std::sqrt(2.0) * s / std::sqrt(std::max(1.0, score_samples)); }
  std::vector<double> off_share;  // each set's off_pose_score; setup
  // Each set's rotational self-similarity (pattern_symmetry.hpp); setup. angle_order: the active
  // set's declared order, set at each update(): its hypotheses 360°/order apart are one look, so
  // a jump does not open the flip check on them (open_flip_on_jump) and a search's angle is taken
  // nearest the last one.
  std::vector<PatternSymmetry> symmetry;
  int angle_order = 1;
  // The level learns from every kFitSampleEvery-th ROI frame (fit_frames counts them): the
  // attainable score on the others only when a judgement needs it; ≤ 1/4 of its cost on a
  // target scoring above the bounds, and the ring's 32 frames span ~130. Sampling every frame
  // until the level is known (8 frames, not 32) was tried (2026-12-06): another needle a lost tip
  // was re-found on went 38 -> 17 false TRACKING poses, but a level learnt over 8 frames in a row
  // is too narrow for what follows — the needle tip re-found beside another object at its full
  // score (0.84, χ² 2.5) stayed UNCERTAIN for good, its frames never teaching the level
  // (pose_envelope_probe: TRACKING 47,299 -> 47,234, other_object_comes_to_60px 40 -> 22 %).
  static constexpr unsigned kFitSampleEvery = 4;
  unsigned fit_frames = 0;
  void keep_continuity(const PoseFrame& frame, PoseEstimate& e) noexcept;
  // A re-acquisition search's winner lies off that line while the line's own place holds a
  // hypothesis scoring with it (tracker.cpp, rival_on_line): the frame cannot tell the target
  // from a twin that covered it. UNCERTAIN, and the line is kept (not forgotten with the search).
  bool line_rival = false;
  bool rival_on_line(const PatternBank& bank, const std::uint16_t* px, const Roi& field_roi, int bits, const PoseEstimate& e,
                     const AnglePrior& last, double t_s) noexcept;
  // The loss came through held frames: the target was at its place (held_*_px) but did not match
  // (another object over its rim, jaws open) — covered or changed, not gone. Set by go_lost,
  // cleared by the search that finds something. A search's pose farther from that place than
  // the pattern's radius opens away_from_held: the poses followed are UNCERTAIN until one is back
  // at the place or their fit, over kAwaySettleFrames frames, is at the target's own level
  // (judge_away_from_held, tracker.cpp says why).
  bool lost_after_hold = false;
  // Since the last hold or loss no TRACKING pose has been measured against its 180° opposite
  // (judge_against_opposite, tracker.cpp says why). Set by hold() and go_lost().
  bool resumed_unvouched = true;
  void judge_against_opposite(const PatternBank& bank, const Measurement& m, PoseEstimate& e) noexcept;
  // This frame's search found something after such a loss (the target covered: another object
  // may be what it found; ContinuityAnchor::forget_keeping_velocity's `covered`).
  bool found_after_hold = false;
  double held_x_px = 0, held_y_px = 0, held_scale = 1;  // the radius: the pattern's at held_scale
  bool away_from_held = false;
  int away_frames = 0;
  double away_excess_sum = 0;
  static constexpr int kAwaySettleFrames = 8;
  std::array<double, kAwaySettleFrames> away_excess{};
  // How far (in one frame's spreads) a re-found target's fit may sit above its old level for good,
  // beyond the noise of the window's mean: on other background its residual differs (a needle tip
  // back from a corner, 20 e⁻/px: log excess 0.10-0.15 where one frame's spread is 0.09); the
  // other object's edge sat 4-8 spreads above (2.5 / 20 e⁻/px). 2 let the edge at 2.5 e⁻/px
  // through on 40 frames (pose_envelope_probe other_object_comes_to_60px); 1 kept it out.
  static constexpr double kAwayOffsetSpreads = 1.0;
  // The target was lost on a frame the split check found torn (a scan glitch: the lower half of
  // the frame shifted), or whose pose jumped where its score did not vouch for it (the other part
  // beyond the cuts' reach). The field scan after it is torn too while the glitch lasts, with the
  // target wholly in the shifted part (no cut of the window straddles the tear): pose_envelope_probe
  // half_shifted_*_frames_40_49, the search on frame 41 took it 5-20 px off, TRACKING on 11 rows
  // at >= 2.5 e-/px. Nothing in that frame tells it from a jump, so the search's pose is
  // UNCERTAIN until an ROI frame confirms it. Set on the lost frame; cleared by the search that
  // finds the target or a TRACKING pose in the held ROI. A real jump's loss is neither: the target
  // scores at its level and leaves the window whole.
  bool lost_on_tear = false;
  // The score level the target kept before that loss (LossPolicy::recent_level()) and how far
  // below it a score still confirms it (the confirmed margin, at least significance_z() SDs of a
  // difference of two scores); 0: none. A torn field scan finds the target's shifted part, or a
  // look-alike, and the ROI frames after it are torn the same way while the glitch lasts, so an
  // ROI frame alone does not confirm the search: a pose followed after a loss on a tear is TRACKING
  // only once it scores at that level again (pose_envelope_probe half_shifted_20px_frames_40_49,
  // the lamella on post at 2.5 e-/px: found 13 px off and turned 91° at 0.62, followed TRACKING at
  // 0.64-0.67 on frames 43-47 where the target had scored 0.73 +- 0.013; the needle tip at 20 e-/px
  // 0.77 against 0.91). Kept across further losses until a pose scores there, or kTearLapseFrames
  // followed poses in a row did not (the target's level changed while it was lost: it does not
  // stay UNCERTAIN for ever), or the target is forgotten.
  double tear_level = 0, tear_margin = 0;
  int tear_below_frames = 0;
  static constexpr int kTearLapseFrames = 2 * ContinuityAnchor::kTrail;
  void check_tear_level(const Measurement& m, PoseEstimate& e) noexcept;
  bool off_held_place(const PoseEstimate& e) const noexcept;
  void judge_away_from_held(PoseEstimate& e) noexcept;
  // A re-acquisition off the line, turned from it and below the line's level (tracker.cpp): the
  // line is kept as for a rival.
  bool turned_off_line(const Measurement& m, const PoseEstimate& e, double t_s) const noexcept;
  // A torn frame (tracker.cpp, torn()): the rows of the footprint scanned first and those
  // scanned last put the target at places that differ by more than their noise allows (χ², 2
  // dof, at max_false_probability over the cuts) and by at least kTornApartPx
  // (split_consistency.hpp) beyond what the target's own motion shears them apart
  // (shear_per_row + scale_per_row) × the rows between them; along the scan lines, which a
  // change of size does not pull apart, shear_per_row alone): it moved mid-scan, or the scan
  // tore. Followed, reported UNCERTAIN with kReasonUnexplained.
  // together (optional): the parts lie clearly together (every cut within kTogetherZ SDs; false
  // when not measured).
  // Parts of the window that move differently (split_consistency.hpp, the tiles): see tracker.cpp.
  bool parts_disagree(const Measurement& m, const PatternBank& bank, double used_scale) const noexcept;
  static constexpr double kTilesApartPx = 0.75, kTilesTurnDeg = 1.0;
  std::uint64_t load_seq = 0;  // ROIs loaded: the split cache's key
  SplitConsistency split_at(const PatternBank& bank, const Measurement& m) const noexcept;
  struct SplitCache {
    std::uint64_t seq = ~std::uint64_t{0};
    const PatternBank* bank = nullptr;
    int j = -1, ux = 0, uy = 0;
    SplitConsistency s;
  };
  mutable SplitCache split_cache;
  bool torn(const Measurement& m, const PatternBank& bank, double used_scale, double shear_per_row,
            double scale_per_row, bool* together = nullptr) const noexcept;
  // How far apart the target's own motion during the scan puts the parts per row, how much the
  // tracked scale against the loaded one adds, and whether the scale is steady enough to judge.
  struct SplitAllowance {
    double shear_per_row = 0, scale_per_row = 0;
    bool steady_scale = false;
  };
  SplitAllowance split_allowance(const PoseFrame& frame, const PoseEstimate& e, int roi_h, double used_scale) const noexcept;
  // The pattern's window at the measured pose reaches the field's edge (tracker.cpp): the match
  // is the best place the pattern still fits, not necessarily the target's. Reported UNCERTAIN
  // with kReasonOutOfField.
  bool at_field_edge(const PoseEstimate& e, double load_scale) const noexcept;
  static constexpr double kTornApartPx = 0.75, kStillPx = 1.0, kStillScale = 0.0025, kStillScaleStep = 0.005;
  double untorn_scale = 1.0;  // the tracked scale after the last accepted frame not found torn (or search)
  // A torn frame holds the tracked scale until the parts lie clearly together again (tracker.cpp,
  // the scale's update): a tear reads as a change of size.
  // Only a scale a frame has vouched for (parts together at it since the search) is held, and
  // for at most kMaxScaleHold frames: a scale from a search on a torn frame, or a real step in
  // size, would otherwise keep every frame after it apart.
  bool scale_held = false, scale_vouched = false;
  int scale_held_frames = 0;
  static constexpr double kTogetherZ = 2.5;
  static constexpr int kMaxScaleHold = 10;
  // Followed poses in a row clearly off the continuity line while its check is open
  // (keep_continuity); at kBackToLineFrames the ROI goes back to the line's place.
  int off_line_frames = 0;
  static constexpr int kBackToLineFrames = 5;
  double scale_step = 0;      // the tracked scale's change from one such frame to the next
  // Its running mean over those frames (gain kScaleRateGain: ~2 frames' memory): the
  // scale's rate with one step's noise halved (a still target's single step reaches 0.27 % at
  // 6 e-/px; a ±25 % ramp over 60 frames keeps ~0.4 % a frame).
  double scale_rate = 0;
  static constexpr double kScaleRateGain = 0.5;
  // The motion model's speed (px per frame) after the last TRACKING frame; -1 after a search.
  double tracking_speed_px = -1;
  // The followed poses' recent speed and turn rate, kept through a loss for the search after it
  // (sheared_by_motion; noted by Tracker::update).
  RecentMotion recent;
  // A full-field scan takes the target's rows over a long time: a target still moving as it was
  // last followed is sheared and stretched in it by more than kSearchShearPx across its rows,
  // and the search's rigid pose of it is biased by about half that, along the target's content
  // (the needle tip at 470 px/s: ~10 px of shear, poses 3.5-4 px off). Such a search pose waits
  // for an ROI frame, whose rows take a few ms, to confirm it. 3 px keeps that bias within half
  // the false-pose rule; the benchmark's gripper (~80 px/s, 2.7 px) stays vouched for.
  bool sheared_by_motion(const PoseFrame& frame, const Roi& roi, const PatternBank& bank, double at_scale) const noexcept;
  static constexpr double kSearchShearPx = 3.0;
  double frame_dwell_ns = 0;  // the pixel dwell of the frame being measured (0: not known)
  // The time from the last frame's mid-scan to this one's (0: not known), and that mid-scan.
  double frame_period_s = 0, last_mid_s = 0;

  // Flip check (a near-symmetric target, e.g. a lamella, scores almost alike turned by 180°):
  // after a search without a trusted angle prior whose choice does not lead the opposite
  // hypothesis by a significant margin, every tracked frame also measures the opposite one
  // (one binned FFT and a walk, ~50 µs) and sums the score differences; the poses are
  // UNCERTAIN until the sum is significant either way (then the winner is tracked).
  bool flip_open = false;
  // Σ and Σ² of (score of the tracked hypothesis − score of the opposite one) over n frames.
  struct FlipLead {
    double sum = 0, sum2 = 0;
    int n = 0;
    void add(double d) noexcept { sum += d, sum2 += d * d, ++n; }
    int verdict(double z_normal) const noexcept;
  };
  FlipLead flip_lead;
  // With a shape mask: the same of the hypotheses' binned whole-circle scores (tracker.cpp,
  // settle_flip), which must agree with the masked ones.
  FlipLead flip_circle;
  bool shape_masked = false;  // the active set's pattern has a user's shape mask; set at each update()
  double score_samples = 1.0;  // independent noise samples under the mask (mask pixels × Σk²): the active set's
  std::vector<double> set_score_samples;  // each set's (its shape mask's pixels, else the circle's); setup
  // SD of one frame's difference of two ZNCC scores near s under detector noise alone:
  // √2·(1 − s²)/√N_eff (the ZNCC's sampling SD, two nearly independent measurements).
  double flip_sd(double s) const noexcept {
    return std::sqrt(2.0) * (1.0 - std::min(1.0, s * s)) / std::sqrt(std::max(1.0, score_samples));
  }
  double significance_z() const noexcept { return significance_z_value; }
  static double upper_normal_quantile(double p) noexcept;
  static double student_t(double z, int nu) noexcept;
  // prior_chose: the last tracked angle was known and the search's winner agrees with it.
  void open_flip_check(const Measurement& m, bool prior_chose, bool censored) noexcept;

  // Search check (a real micrograph has look-alikes: the warped lamella-on-post crop at
  // 1 e-/px has one ~200 px away, turned −90°, scoring as the target does): a search's result
  // must lead the best candidate at another place by a significant margin, summed over the
  // searches that agree on the place; until then it is UNCERTAIN and the field is searched
  // again on the next frame.
  int search_n = 0;
  int search_episode = 0;  // searches that found something since the target was last settled
  int search_place_n = 0;  // of them, the last ones won at the last winner's place (any angle)
  double search_sum = 0, search_x = 0, search_y = 0, search_phi = 0;
  bool search_settled(const Measurement& m, const PoseEstimate& e) noexcept;
  template <class Place>
  bool settle_flip(const PatternBank& bank, Measurement& m, PoseEstimate& e, const Place& place) noexcept;
  // The hypothesis 180° from m, measured as the search measures it (binned FFT at φ + 180°
  // around m's place, the walk): the flip check's other side.
  Measurement opposite_of(const PatternBank& bank, const Measurement& m, PoseEstimate& e) noexcept;
  // This frame's pose surprised the motion check (check_motion ran its search): a jump the
  // target's turned look-alike beside it can explain (open_flip_on_jump).
  bool surprised = false;
  template <class Place>
  void open_flip_on_jump(const PatternBank& bank, const Measurement& m, PoseEstimate& e, double t_s, const Place& place) noexcept;
  // level_cap: the most the target's own level learns from this pose (a search frame's
  // attainable score with tracker.attainable_pattern_noise; 1: the score itself).
  void accept(PoseEstimate& e, const PoseFrame& frame, bool fresh, double level_cap = 1.0) noexcept;
};

}  // namespace sempose::pose
