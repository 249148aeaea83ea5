// The tracker: builds the stages at setup and runs them in sequence per frame.
//   frame → (bad / re-acquire / full field?) → start search  ─┐
//                                          → ROI (resampled by 1/scale) load → FFT peak at the
//                                            predicted angle → orientation walk + fit
//                                            → recovery sweep → refinement seam → scale probe ─┤
//   explained check → loss policy (accept / coast / lost) → motion model, scale
//   → temporal filter → PoseEstimate
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
#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/loss_policy.hpp"
#include "sempose/pose/motion_model.hpp"
#include "sempose/pose/orientation_walk.hpp"
#include "sempose/pose/pattern_bank.hpp"
#include "sempose/pose/pose_filter.hpp"
#include "sempose/pose/pose_refinement.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/roi_loader.hpp"
#include "sempose/pose/roi_rescaler.hpp"
#include "sempose/pose/scale_probe.hpp"
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

// (1 − r²)/(1 − a²): the variance a fit with gain and offset leaves (share 1 − r² of the
// window's) over what the noise model predicts it leaves (1 − a², a the attainable score).
// The floor keeps a noise-free window finite.
float normalised_chi2(double score, double attainable) noexcept {
  const double left = 1.0 - std::clamp(score, 0.0, 1.0) * std::clamp(score, 0.0, 1.0);
  const double noise = 1.0 - attainable * attainable;
  return static_cast<float>(left / std::max(noise, 1e-4));
}
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
  RoiRescaler rescaler;
  const ScaleProbe scale_probe;
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
  // The target's scale (size over the pattern's): each tracked ROI is resampled by 1/scale.
  // Learnt from the accepted frames' scale readings, kept across a loss (the magnification
  // has not changed), back to 1 when the target is forgotten (new pattern set, REACQUIRE).
  double scale = 1.0;
  static constexpr double kScaleGain = 0.5;         // share of a frame's reading taken at once
  static constexpr double kScaleMin = 0.7, kScaleMax = 1.45;  // beyond: the ROI cannot hold the target
  // Closer to 1 than this: the raw ROI is loaded as scanned. Resampling costs ~40 µs, and at
  // 1 % its interpolation blur cost more angle accuracy than the size error it removes; the
  // reading itself runs 0.6–1.7 % high at 20–2.5 e⁻/px on unscaled targets (README: Known
  // limitations), so below 2.5 % a reading is not acted on (pose_accuracy_bench).
  static constexpr double kRescaleFrom = 0.025;
  config::ScanLimits field;  // the scan field's size (from setup, then from the frames)
  std::atomic<bool> reacquire{false};
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
        sizes(s),
        angles{static_cast<int>(std::lround(360.0 / c.angle_step_deg)), c.angle_step_deg},
        fine_mask(s.pattern_px, c.circular_mask, 8, mask_inset_px(c)),
        half_mask(s.pattern_px / 2, c.circular_mask, 8, mask_inset_px(c) / 2),
        coarse_mask(s.coarse_pattern_px, c.circular_mask),
        half(s.half_fft_px, s.half_fft_px, half_mask),
        coarse(good_fft_size(s.coarse_max_w), good_fft_size(s.coarse_max_h), coarse_mask),
        scorer(fine_mask, s.roi_fft_px),
        loader(c.prefilter_passes, s.roi_fft_px, scorer, half),
        rescaler(s.roi_fft_px),
        scale_probe(scorer),
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

  void use_noise_floors_of(std::uint8_t set) noexcept {
    if (set < noise_floors.size())
      loss.set_noise_floors(std::min(1.0f, noise_floors[set].roi * floor_scale_now),
                            std::min(1.0f, noise_floors[set].field * floor_scale_now));
  }
  double attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy) const noexcept;
  void calibrate_noise_floors(const config::ScanLimits& limits);
  void forget_everything() noexcept;

  PoseEstimate update(const PoseFrame& frame) noexcept;
  Measurement track(const PatternBank& bank) noexcept;
  void to_estimate(const Measurement& m, int origin_x, int origin_y, PoseEstimate& e) const noexcept;
  void go_lost() noexcept;
  void accept(PoseEstimate& e, const PoseFrame& frame, bool fresh) noexcept;
};

// The ZNCC the target itself would reach in the window at (cx, cy) of a frame: √(S/(S+N)),
// S the window's signal variance, N the noise variance the prefilter leaves. A true match
// explains S; textured background that merely resembles the pattern explains a small part of
// it. N comes from the raw window by Immerkær's estimator (Laplacian-difference kernel, blind
// to linear structure: σ = √(π/2)·Σ|I∗L| / (6(W−2)(H−2))), scaled by the prefilter's noise
// gain; S = window variance − noise. RT, no allocation (one pass over the P×P window).
double Tracker::Impl::attainable_score(const std::uint16_t* px, int w, int h, double cx, double cy) const noexcept {
  const int p = sizes.pattern_px;
  if (w < p || h < p || p < 3) return 0.0;
  const int x0 = std::clamp(static_cast<int>(std::lround(cx - (p - 1) / 2.0)), 0, w - p);
  const int y0 = std::clamp(static_cast<int>(std::lround(cy - (p - 1) / 2.0)), 0, h - p);
  double sum = 0, sum2 = 0, abs_lap = 0;
  for (int y = 0; y < p; ++y) {
    const std::uint16_t* row = px + static_cast<std::size_t>(y0 + y) * w + x0;
    for (int x = 0; x < p; ++x) {
      const double v = row[x];
      sum += v;
      sum2 += v * v;
    }
  }
  for (int y = 1; y + 1 < p; ++y) {
    const std::uint16_t* r0 = px + static_cast<std::size_t>(y0 + y - 1) * w + x0;
    const std::uint16_t* r1 = r0 + w;
    const std::uint16_t* r2 = r1 + w;
    for (int x = 1; x + 1 < p; ++x) {
      const double l = (double(r0[x - 1]) - 2.0 * r0[x] + r0[x + 1]) - 2.0 * (double(r1[x - 1]) - 2.0 * r1[x] + r1[x + 1]) +
                       (double(r2[x - 1]) - 2.0 * r2[x] + r2[x + 1]);
      abs_lap += std::fabs(l);
    }
  }
  const double n = static_cast<double>(p) * p;
  const double var = std::max(0.0, sum2 / n - (sum / n) * (sum / n));
  const double sigma = std::sqrt(M_PI / 2.0) * abs_lap / (6.0 * (p - 2) * (p - 2));
  const double noise = std::min(var, sigma * sigma);
  const double signal = var - noise;
  const double left = signal + prefilter_noise_gain * noise;
  return left > 0 ? std::sqrt(signal / left) : 0.0;
}

// RT: the bank this frame uses: the learned one published last, else the recorded one. A new
// one brings its noise floors (a smaller support lets noise reach higher scores).
const PatternBank& Tracker::Impl::frame_bank(std::uint8_t set) noexcept {
  if (!learned) return *banks[set];
  LearnedBanks& l = learned[set];
  const int k = l.published.load(std::memory_order_acquire);
  l.in_use.store(k, std::memory_order_release);
  const int seen = set * 4 + k;  // changes with the set or the slot
  if (seen != bank_seen) {
    bank_seen = seen;
    floor_scale_now = k < 0 ? 1.0f : l.floor_scale[k];
    use_noise_floors_of(set);
  }
  return k < 0 ? *banks[set] : *l.slot[k];
}

bool Tracker::Impl::maintain_appearance() {
  if (!observer) return false;
  // The model and the slots have one writer: a second caller (a worker thread and an offline
  // loop at once) returns at once instead of waiting.
  if (maintaining.test_and_set(std::memory_order_acquire)) return false;
  struct Release {
    std::atomic_flag& f;
    ~Release() { f.clear(std::memory_order_release); }
  } release{maintaining};
  const AppearanceStats* batch = observer->take();
  if (batch == nullptr) return false;
  const std::uint8_t set = batch->set;
  AppearanceDecision d = model->update(*batch);
  observer->give_back();
  if (!d.accepted) {
    appearance_rejected.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  LearnedBanks& l = learned[set];
  const int cur = l.published.load(std::memory_order_acquire);
  // The other slot is free once update() has picked up the current one.
  if (l.in_use.load(std::memory_order_acquire) != cur) {
    appearance_deferred.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  const int next = cur == 0 ? 1 : 0;
  std::string why;
  std::unique_ptr<const PatternBank> bank = PatternBank::with_support(*banks[set], d.support, why);
  if (!bank) {
    appearance_rejected.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  l.floor_scale[next] = static_cast<float>(std::sqrt(banks[set]->mean_support_count() / bank->mean_support_count()));
  l.slot[next] = std::move(bank);
  l.published.store(next, std::memory_order_release);
  appearance_accepted.fetch_add(1, std::memory_order_relaxed);
  appearance_support.store(d.support_fraction, std::memory_order_relaxed);
  return true;
}

// Setup only (allocates): the noise floors of every pattern set, measured by running the real
// update() on frames of uniform 8-bit white noise — a tracking ROI at an angle spread over the
// circle and a full field (capped at kNullFieldMax per side) — kNullTrials each; the floor is
// mean + kNullSigmas·sd of the best scores. Deterministic (fixed seed): every start gives the
// same floors.
void Tracker::Impl::calibrate_noise_floors(const config::ScanLimits& limits) {
  const int fw = std::min(limits.field_w, kNullFieldMax), fh = std::min(limits.field_h, kNullFieldMax);
  std::vector<std::uint16_t> noise(static_cast<std::size_t>(fw) * fh);
  std::uint64_t rng = 0x9E3779B97F4A7C15ull;
  auto fill = [&](std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      rng ^= rng << 13;
      rng ^= rng >> 7;
      rng ^= rng << 17;
      noise[i] = static_cast<std::uint16_t>(rng >> 56);
    }
  };
  auto floor_of = [](const std::vector<double>& v) {
    double m = 0, q = 0;
    for (double x : v) m += x;
    m /= static_cast<double>(v.size());
    for (double x : v) q += (x - m) * (x - m);
    const double sd = std::sqrt(q / static_cast<double>(v.size() - 1));
    return static_cast<float>(std::min(1.0, m + kNullSigmas * sd));
  };
  loss.set_calibrating(true);
  learning = false;
  loss.set_noise_floors(-1.0f, -1.0f);
  noise_floors.assign(banks.size(), NoiseFloor{});
  const std::uint8_t keep = active.load(std::memory_order_relaxed);
  for (std::size_t set = 0; set < banks.size(); ++set) {
    active.store(static_cast<std::uint8_t>(set), std::memory_order_relaxed);
    std::vector<double> roi_scores, field_scores;
    for (int k = 0; k < kNullTrials; ++k) {
      PoseFrame frame;
      frame.field_w = fw;
      frame.field_h = fh;
      frame.bits = 8;
      frame.pixels = noise.data();
      // Full field: the start search.
      forget_everything();
      fill(noise.size());
      frame.roi = {0, 0, fw, fh};
      field_scores.push_back(update(frame).score);
      // Tracking ROI at the field's centre, predicted at an angle spread over the circle.
      const int rw = std::min(sizes.roi_px, fw), rh = std::min(sizes.roi_px, fh);
      forget_everything();
      motion.accept(fw / 2.0, fh / 2.0, rt::wrap_deg(k * (360.0 / kNullTrials) + 7.0), true);
      tracking = true;
      fill(static_cast<std::size_t>(rw) * rh);
      frame.roi = {(fw - rw) / 2, (fh - rh) / 2, rw, rh};
      roi_scores.push_back(update(frame).score);
    }
    noise_floors[set].roi = floor_of(roi_scores);
    noise_floors[set].field = floor_of(field_scores);
  }
  active.store(keep, std::memory_order_relaxed);
  forget_everything();
  loss.set_calibrating(false);
  learning = observer != nullptr;
  use_noise_floors_of(keep);
  field.field_w = limits.field_w;
  field.field_h = limits.field_h;
}

void Tracker::Impl::forget_everything() noexcept {
  go_lost();
  loss.forget_target();
  scale = 1.0;
  motion = MotionModel(cfg.predict_velocity);  // also the last angle a search's tie-break uses
}

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
  if (observer) observer->discard();
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
  const PatternBank& bank = frame_bank(set);
  const bool full_field = field.is_full_field(roi.x, roi.y, roi.w, roi.h);
  if (reacquire.exchange(false, std::memory_order_relaxed)) {
    go_lost();
    // Commanded, or a new magnification: the target's look may have changed; the new
    // pattern set has its own noise floors and is matched at its own size first.
    loss.forget_target();
    scale = 1.0;
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
    e.scale = scale;  // the start search matches at the pattern's size (README: Known limitations)
    const double attainable = m.valid ? attainable_score(px, roi.w, roi.h, e.x_px - roi.x, e.y_px - roi.y) : 0.0;
    if (m.valid) e.chi2 = normalised_chi2(e.score, attainable);
    if (loss.found(m, attainable)) {
      accept(e, frame, true);
    } else {
      e.state = TrackState::kAcquiring;
      // Not found is a low score too when it is only below the field's floor, the attainable
      // score or the target's own level.
      e.reason_bits = m.valid ? static_cast<std::uint8_t>(loss.weak_reasons(m) | kReasonLowScore)
                              : static_cast<std::uint8_t>(kReasonFlatFrame);
      go_lost();
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
  if (scored.w < pattern_px || scored.h < pattern_px || !loader.load(load_px, scored.w, scored.h, load_stride, load_bits)) {
    e.state = TrackState::kLost;
    e.reason_bits = static_cast<std::uint8_t>((scored.w < pattern_px || scored.h < pattern_px) ? kReasonOutOfField
                                                                                                  : kReasonFlatFrame);
    e.score = 0;
    go_lost();
    return e;
  }
  Measurement m = track(bank);
  const ScaleReading reading = scale_probe.read(bank, m);
  to_estimate(m, scored.x, scored.y, e);
  if (rescaled) {
    // The pose in the resampled ROI, back to the scanned one.
    e.x_px = scored.x + RoiRescaler::to_raw(e.x_px - scored.x, std::min(scored.w, sizes.roi_fft_px), used_scale);
    e.y_px = scored.y + RoiRescaler::to_raw(e.y_px - scored.y, std::min(scored.h, sizes.roi_fft_px), used_scale);
    e.meas_x_px = e.x_px;
    e.meas_y_px = e.y_px;
  }
  e.scale = reading.valid ? used_scale * reading.factor : scale;
  // The attainable score is ≤ 1, so a score at or above explained_threshold passes the
  // check whatever it is: measured only when it can matter (~30 µs a frame saved).
  if (e.score < cfg.explained_threshold) {
    m.attainable = static_cast<float>(attainable_score(frame.pixels, roi.w, roi.h, e.x_px - roi.x, e.y_px - roi.y));
    e.chi2 = normalised_chi2(e.score, m.attainable);
  }
  if (m.unsettled) e.reason_bits |= kReasonAngleUnsettled;
  if (motion.prediction_outside(field.field_w, field.field_h)) e.reason_bits |= kReasonOutOfField;
  switch (loss.judge(m)) {
    case FrameVerdict::kAccept:
      accept(e, frame, false);
      if (reading.valid) scale = std::clamp(scale + kScaleGain * (e.scale - scale), kScaleMin, kScaleMax);
      // A good frame teaches the appearance model (RT: sums into a preallocated batch). It reads
      // the pixels the walk was scored on (the ROI resampled to the pattern's size if rescaled).
      if (learning && e.reason_bits == 0 && m.score >= cfg.appearance.min_score) {
        const double c = (pattern_px - 1) / 2.0;
        observer->observe(set, scorer.roi(), scorer.roi_w(), scorer.roi_h(), load_px, load_stride, load_bits, m.ux + m.dx + c,
                          m.uy + m.dy + c, (m.j + m.dj) * angles.step_deg);
      }
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
  // Kept for the appearance learner (the bank spec takes the originals).
  std::vector<PatternImage> prior_patterns, prior_shapes;
  if (cfg.appearance.enabled)
    for (const PatternSet& ps : sets) {
      prior_patterns.push_back(ps.image);
      prior_shapes.push_back(ps.mask);
    }
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
  {
    // White-noise variance the prefilter keeps: Σk² of its 2-D kernel, the 5-tap binomial
    // [1 4 6 4 1]/16 convolved with itself once per pass, separable.
    std::vector<double> k{1.0};
    for (int pass = 0; pass < cfg.prefilter_passes; ++pass) {
      std::vector<double> next(k.size() + 4, 0.0);
      const double b[5] = {1 / 16.0, 4 / 16.0, 6 / 16.0, 4 / 16.0, 1 / 16.0};
      for (std::size_t i = 0; i < k.size(); ++i)
        for (int j = 0; j < 5; ++j) next[i + static_cast<std::size_t>(j)] += k[i] * b[j];
      k.swap(next);
    }
    double g = 0;
    for (double v : k) g += v * v;
    t.prefilter_noise_gain = g * g;
  }
  if (cfg.appearance.enabled) {
    // The learner's references: each set's recorded pattern, prefiltered like the frames; its
    // priors: the shape masks (the learned support never leaves them).
    const int n = pattern_px;
    t.observer = std::make_unique<AppearanceObserver>(n, t.fine_mask.bitmap(), cfg.appearance.frames_per_update,
                                                      t.prefilter_noise_gain, cfg.prefilter_passes);
    std::vector<std::vector<float>> refs;
    std::vector<std::vector<float>> priors;
    for (std::size_t i = 0; i < sets.size(); ++i) {
      std::vector<float> ref(static_cast<std::size_t>(n) * n);
      for (std::size_t k = 0; k < ref.size(); ++k) ref[k] = static_cast<float>(prior_patterns[i].pixels[k]);
      prefilter_pattern(ref.data(), n, cfg.prefilter_passes);
      t.observer->add_reference(ref);
      refs.push_back(std::move(ref));
      std::vector<float> prior;
      if (!prior_shapes[i].empty()) {
        prior.assign(static_cast<std::size_t>(n) * n, 0.0f);
        for (std::size_t k = 0; k < prior.size(); ++k) prior[k] = prior_shapes[i].pixels[k] != 0 ? 1.0f : 0.0f;
        dilate_disk(prior, n, cfg.shape_mask_margin_px);
      }
      priors.push_back(std::move(prior));
    }
    t.model = std::make_unique<AppearanceModel>(cfg.appearance, n, t.fine_mask.bitmap(), std::move(refs), std::move(priors));
    t.learned = std::make_unique<Impl::LearnedBanks[]>(sets.size());
  }
  t.calibrate_noise_floors(limits);
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

std::size_t Tracker::pattern_set_count() const noexcept { return impl_->banks.size(); }
float Tracker::noise_floor_roi(std::size_t set) const noexcept {
  return set < impl_->noise_floors.size() ? impl_->noise_floors[set].roi : -1.0f;
}
float Tracker::noise_floor_field(std::size_t set) const noexcept {
  return set < impl_->noise_floors.size() ? impl_->noise_floors[set].field : -1.0f;
}
std::uint8_t Tracker::pattern_set() const noexcept { return impl_->active.load(std::memory_order_relaxed); }
double Tracker::nm_per_px() const noexcept { return impl_->nm_per_px[impl_->active.load(std::memory_order_relaxed)]; }
void Tracker::request_reacquire() noexcept { impl_->reacquire.store(true, std::memory_order_relaxed); }

bool Tracker::maintain_appearance() { return impl_->maintain_appearance(); }

void Tracker::start_appearance_worker() {
  Impl& t = *impl_;
  if (!t.observer || t.worker.joinable()) return;
  t.worker = std::thread([&t] {
    const timespec period{0, 20'000'000};
    while (!t.worker_stop.load(std::memory_order_relaxed)) {
      t.maintain_appearance();
      nanosleep(&period, nullptr);
    }
  });
}

Tracker::AppearanceStatus Tracker::appearance_status() const noexcept {
  const Impl& t = *impl_;
  AppearanceStatus s;
  s.accepted = t.appearance_accepted.load(std::memory_order_relaxed);
  s.rejected = t.appearance_rejected.load(std::memory_order_relaxed);
  s.deferred = t.appearance_deferred.load(std::memory_order_relaxed);
  s.support_fraction = t.appearance_support.load(std::memory_order_relaxed);
  return s;
}

std::size_t Tracker::memory_bytes() const noexcept {
  const Impl& t = *impl_;
  std::size_t b = t.half.buffer_bytes() + t.coarse.buffer_bytes();
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
