// Tracker setup: checks the pattern sets and settings, builds the stages, measures the noise
// floors. Allocates; never called on an RT thread.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "sempose/pose/attainable_score.hpp"
#include "sempose/pose/off_pose_score.hpp"
#include "sempose/pose/pattern_rim.hpp"
#include "tracker_impl.hpp"

namespace sempose::pose {

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
  tau_estimate.reset();  // the calibration's frames are white noise, not the detector's
  loss.set_calibrating(false);
  learning = observer != nullptr;
  use_noise_floors_of(keep);
  field.field_w = limits.field_w;
  field.field_h = limits.field_h;
}

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
  if (limits.field_w < pattern_px || limits.field_h < pattern_px)
    return fail("the scan field (" + std::to_string(limits.field_w) + "x" + std::to_string(limits.field_h) +
                " px) is smaller than the pattern (" + std::to_string(pattern_px) + "x" + std::to_string(pattern_px) + " px)");
  // The ROI is at most the field's shorter side: a field as small as the pattern leaves it one
  // place, every pose on the ROI's edge and never TRACKING, without a word (review of the edge rule).
  if (std::min({cfg.roi_size_px, limits.field_w, limits.field_h}) <= pattern_px)
    return fail("the ROI (tracker.roi_size_px " + std::to_string(cfg.roi_size_px) + ", at most the " +
                std::to_string(limits.field_w) + "x" + std::to_string(limits.field_h) + " field's shorter side) is not larger than the " +
                std::to_string(pattern_px) + " px pattern: it leaves the target no room to move");

  const EngineSizes sizes = EngineSizes::of(cfg, pattern_px, limits.field_w, limits.field_h);
  auto impl = std::make_unique<Impl>(cfg, sizes, limits.field_w, limits.field_h);
  Impl& t = *impl;
  t.measure_tau = !(cfg.detector_tau_ns > 0) && cfg.measure_detector_tau;
  t.check_told_tau = cfg.detector_tau_ns > 0 && cfg.measure_detector_tau;
  std::string told_note;  // the sets whose own noise overrules their told lag (a warning)
  std::string rim_note;   // the sets whose position information lies at their rim (a warning)
  // Kept for the appearance learner (the bank spec takes the originals).
  std::vector<PatternImage> prior_patterns, prior_shapes;
  if (cfg.appearance.enabled)
    for (const PatternSet& ps : sets) {
      prior_patterns.push_back(ps.image);
      prior_shapes.push_back(ps.mask);
    }
  {
    // The noise variance the prefilter keeps: Σk² of its 2-D kernel for white noise (the
    // appearance observer), more for the detector's line-correlated noise (attainable score).
    t.prefilter_noise = PrefilterNoiseGain(cfg.prefilter_passes);
    t.prefilter_noise_gain = t.prefilter_noise.white();
  }
  for (std::size_t i = 0; i < sets.size(); ++i) {
    // A shape mask says which pixels are the target: its rim is the target's own.
    if (sets[i].mask.empty()) {
      const std::string rim = rim_warning(
          rim_information_share(sets[i].image.pixels.data(), sets[i].image.width, cfg.prefilter_passes));
      if (!rim.empty()) rim_note += (rim_note.empty() ? "" : "; ") + ("pattern set " + std::to_string(i) + ": " + rim);
    }
    PatternBankSpec spec;
    spec.pattern = std::move(sets[i].image);
    spec.shape = std::move(sets[i].mask);
    spec.shape_margin_px = cfg.shape_mask_margin_px;
    spec.prefilter_passes = cfg.prefilter_passes;
    spec.angle_step_deg = cfg.angle_step_deg;
    spec.coarse_step_deg = cfg.search_angle_step_deg;
    spec.coarse_factor = sizes.search_factor;
    std::string why;
    auto bank = PatternBank::build(spec, {t.fine_mask, t.half_mask, t.half, t.coarse_mask, t.coarse, t.coarse_wide.get()}, why);
    if (!bank) return fail("pattern set " + std::to_string(i) + ": " + why);
    // The refinement's fit template is built for every set (refine() returns at once while
    // tracker.refine.enabled is off); too small a pattern for it only matters when it is on
    // (found probing: pattern_size_px 16 was refused naming tracker.refine with it off).
    if (!t.refinement.add_set(*bank, spec.pattern, limits.bits) && cfg.refine.enabled)
      return fail("pattern set " + std::to_string(i) + ": too few pixels for tracker.refine's fit (tracker.refine.enabled is on; "
                  "a larger tracker.pattern_size_px, or refinement off)");
    // The pattern's own noise as the bank measured it for σ (attainable_score.hpp).
    t.pattern_factor.push_back(cfg.attainable_pattern_noise
                                   ? pattern_attainable_factor(spec.pattern.pixels.data(), spec.pattern.width,
                                                               {bank->pattern_noise_var(), bank->pattern_noise_rho()},
                                                               t.prefilter_noise)
                                   : 1.0);
    // A shape mask scores on its own pixels only, so the scores' noise is that of fewer samples
    // than the circle's (the flip, search and below-level checks' SD, flip_sd).
    t.set_score_samples.push_back((bank->has_shape() ? bank->mean_support_count() : static_cast<double>(t.fine_mask.count())) *
                                  t.prefilter_noise_gain);
    t.off_share.push_back(off_pose_score(*bank, cfg.angle_step_deg));
    t.symmetry.push_back(measure_symmetry(*bank, nearest_off_pose_score(*bank, cfg.angle_step_deg)));
    if (cfg.correct_scan_motion) t.scan_motion.emplace_back(*bank);
    t.banks.push_back(std::move(bank));
    t.nm_per_px.push_back(sets[i].nm_per_px);
    t.pattern_lag_px.push_back(DetectorLag::px(cfg.detector_tau_ns, sets[i].dwell_ns));
    t.pattern_dwell_ns.push_back(sets[i].dwell_ns);
    // A set of unknown dwell: the lag its own noise shows (a pattern recorded through the
    // detector at the tracking dwell has the frames' lag: none to take out), 0 for a clean crop.
    // Told τ: the lag the set's dwell_ns implies, checked against the same reading.
    const PatternImage& im = spec.pattern;
    const bool read = (t.measure_tau && sets[i].dwell_ns == 0) || t.check_told_tau;
    const PatternLineRho reading = read ? read_pattern_line_rho(im.pixels.data(), im.width, im.height) : PatternLineRho{};
    const double told_rho = sets[i].dwell_ns > 0 && t.check_told_tau
                                ? std::exp(-static_cast<double>(sets[i].dwell_ns) / cfg.detector_tau_ns)
                                : 0.0;
    const bool overruled =
        t.check_told_tau && reading.readable() && DetectorTauEstimator::told_disagrees(told_rho, reading.lag_rho());
    t.pattern_told_overruled.push_back(overruled ? 1 : 0);
    t.pattern_measured_rho.push_back(reading.lag_rho());
    if (overruled) {
      ++t.patterns_overruled;
      char b[256];
      std::snprintf(b, sizeof b,
                    "%spattern set %zu: its own noise shows line_rho %.2f (%d tiles), tracker.detector_tau_ns %.0f at its "
                    "dwell_ns %u implies %.2f (lag %.2f px, told %.2f px): its measured lag is used",
                    told_note.empty() ? "" : "; ", i, reading.rho, reading.open_tiles, cfg.detector_tau_ns, sets[i].dwell_ns,
                    told_rho, DetectorTauEstimator::lag_of_rho(reading.lag_rho()), DetectorTauEstimator::lag_of_rho(told_rho));
      told_note += b;
    }
  }
  t.score_samples = static_cast<double>(t.fine_mask.count()) * t.prefilter_noise_gain;
  // The split check's noise: the score noise model's pixels per independent sample.
  t.split.set_noise_inflation(static_cast<double>(t.fine_mask.count()) / std::max(1.0, t.score_samples));
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
    // The template blend's weights: the recorded pattern's noise (measured by the bank on the
    // raw pattern) through the prefilter, per pixel, like the observer's frame noise.
    for (std::size_t i = 0; i < t.banks.size(); ++i)
      t.model->set_pattern_noise(static_cast<std::uint8_t>(i), t.banks[i]->pattern_noise_var() * t.prefilter_noise_gain,
                                 t.banks[i]->pattern_noise_var() * t.prefilter_noise_gain *
                                     (1.0 - t.prefilter_noise.lag(2) / t.prefilter_noise.lag(0)) / 2.0);
    t.learned = std::make_unique<Impl::LearnedBanks[]>(sets.size());
  }
  t.calibrate_noise_floors(limits);
  status = rt::Status::success();
  if (t.half.execute_allocates() || t.coarse.execute_allocates() || (t.coarse_wide && t.coarse_wide->execute_allocates())) {
    status.message = "tracker: warning: no allocation-free FFTW plan found for " + std::to_string(sizes.roi_fft_px) +
                     "x" + std::to_string(sizes.roi_fft_px) + " or the coarse size; the loop may call malloc";
  }
  if (!told_note.empty()) status.message += (status.message.empty() ? "tracker: warning: " : "; ") + told_note;
  if (!rim_note.empty()) status.message += (status.message.empty() ? "tracker: warning: " : "; ") + rim_note;
  return std::unique_ptr<Tracker>(new Tracker(std::move(impl)));
}

double Tracker::likeness(const Tracker& other) const {
  constexpr int kMaxShift = 4, kShiftStep = 2, kAngleStride = 2;
  double best = -1.0;
  for (const auto& mine : impl_->banks) {
    for (const auto& theirs : other.impl_->banks) {
      const int n = mine->size_px();
      if (theirs->size_px() != n) continue;
      const float* b = theirs->pattern(0);  // as recorded (angle 0)
      const int stride = std::max(1, static_cast<int>(std::lround(kAngleStride * mine->angles() / 360.0)));
      for (int j = 0; j < mine->angles(); j += stride) {
        const float* a = mine->pattern(j);
        for (int dy = -kMaxShift; dy <= kMaxShift; dy += kShiftStep) {
          for (int dx = -kMaxShift; dx <= kMaxShift; dx += kShiftStep) {
            double dot = 0;
            for (int y = std::max(0, -dy); y < n - std::max(0, dy); ++y) {
              const float* ra = a + static_cast<std::size_t>(y + dy) * n;
              const float* rb = b + static_cast<std::size_t>(y) * n;
              for (int x = std::max(0, -dx); x < n - std::max(0, dx); ++x) dot += static_cast<double>(ra[x + dx]) * rb[x];
            }
            best = std::max(best, dot);  // both zero-mean, unit norm over their supports: ≈ ZNCC
          }
        }
      }
    }
  }
  return best;
}

}  // namespace sempose::pose
