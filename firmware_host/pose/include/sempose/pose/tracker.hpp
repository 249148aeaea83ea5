// One target's pose tracker: the pose engine's stages in sequence (README: How a pose is
// found). create() is setup (allocates, plans FFTs); every other method is RT-safe: noexcept,
// no heap allocation, no locks, no I/O.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "sempose/config/scan_config.hpp"
#include "sempose/config/tracker_config.hpp"
#include "sempose/pose/pattern_image.hpp"
#include "sempose/pose/pattern_symmetry.hpp"
#include "sempose/pose/pose_frame.hpp"
#include "sempose/pose/track_state.hpp"
#include "sempose/rt/result.hpp"

namespace sempose::pose {

struct PoseEstimate {
  TrackState state = TrackState::kAcquiring;
  std::uint8_t reason_bits = kReasonNone;  // LostReason bits
  double x_px = 0;      // full-field px, README: Conventions (centre of the pattern)
  double y_px = 0;
  double phi_deg = 0;   // (-180, 180]
  // This frame's own measurement; equal to x_px, y_px, phi_deg unless tracker.filter is on
  // (then those are the filtered pose).
  double meas_x_px = 0, meas_y_px = 0, meas_phi_deg = 0;
  // The target's size on screen over the pattern's (magnification, working distance): the
  // tracker resamples each ROI by 1/scale so the engine matches at the pattern's own size.
  double scale = 1.0;
  float score = 0;      // ZNCC in [-1, 1]
  float psr = 0;        // peak-to-sidelobe ratio of the position peak
  // Normalised χ² of the match: the share of the window's variance the pattern (with gain and
  // offset) leaves unexplained, 1 − score², over the share the noise model predicts,
  // 1 − attainable² (README: Conventions). ~1: the model explains the window up to noise;
  // a wrong scale, a look-alike or a torn frame leaves structure unexplained (≫ 1). 0: not
  // measured (no match, or a score at or above tracker.explained_threshold, which passes).
  float chi2 = 0;
  // 1σ of this frame's measured pose (meas_x_px, meas_y_px, meas_phi_deg, scale) from the fit's
  // sandwich covariance (pose_uncertainty.hpp), calibrated (README: Uncertainty). 0: not
  // measured (no match, or a frame of the start search).
  double sigma_x_px = 0, sigma_y_px = 0, sigma_phi_deg = 0, sigma_scale = 0;
  std::uint8_t pattern_set = 0;
  // The pattern set's declared rotational order (Tracker::symmetry, README: Symmetric targets):
  // the target looks the same turned by 360°/angle_order, so phi_deg is known modulo that only.
  // Within it the angle keeps to the continuity line (the walk follows the turn; a search with a
  // last angle takes the look nearest it); which of the looks a first search took is
  // unobservable. 1: the angle is known in full.
  std::uint8_t angle_order = 1;
  int angle_steps = 0;  // correlations spent on orientation this frame
  bool searched = false;  // this frame ran the full-field start search
  // When the beam passed the measured pose point (the frame's clock, ns): the scan start plus
  // the share of the scan before the pose's row. The time the pose is valid for: a full-field
  // frame shows a moving target where it was when its rows were scanned, up to half the field's
  // scan time (~39 ms at 640×480, 250 ns) from mid-scan; an ROI frame, centred on the target,
  // about mid-scan. Mid-scan for a frame without a measured pose; 0 when the frame has no scan
  // times.
  std::int64_t t_beam_ns = 0;
  // The tracker follows this pose (its next ROI is placed from it): TRACKING, or UNCERTAIN at
  // an accepted pose (a first start's search frame, a doubted ROI frame). False for a search
  // not yet told from a look-alike (UNCERTAIN, searched again), LOST and ACQUIRING.
  bool followed = false;
  // tracker.refine's outcome for this frame's measurement (FitStatus: 0 off or not reached,
  // 1 refined, 2 diverged — the walk's pose kept —, 3 skipped).
  std::uint8_t refine_status = 0;
  // Set by the pipeline (TrackingStep), not the tracker: a target with the same pattern is on
  // this pose's place (UNCERTAIN), or this frame runs the search sempose started because of it
  // (README: Several targets).
  bool look_alike = false;
};

// One pattern per magnification step.
struct PatternSet {
  PatternImage image;
  double nm_per_px = 1.0;
  // Optional shape mask, pattern-sized, non-zero = the target's own pixels (the rest, e.g.
  // the substrate around a needle, is left out of the exact scores). Empty = the circle.
  PatternImage mask;
  // The pixel dwell it was recorded at (0: lag-free): with TrackerConfig::detector_tau_ns the
  // detector's lag at this dwell against the frame's is taken out of x.
  std::uint32_t dwell_ns = 0;
};

class Tracker {
 public:
  // Setup: pattern banks, FFTW plans (FFTW_MEASURE), spectra. nullptr + message on error.
  // limits: the scan field (field_w × field_h).
  static std::unique_ptr<Tracker> create(const config::TrackerConfig& config, std::vector<PatternSet> sets,
                                         const config::ScanLimits& limits, rt::Status& status);
  ~Tracker();
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  // Full field while acquiring / lost, else the ROI at the predicted pose clamped to the field.
  Roi next_roi() const noexcept;
  // One finished frame for this target (frame.roi says where it was scanned).
  PoseEstimate update(const PoseFrame& frame) noexcept;
  // Switches the magnification step; out of range: ignored, returns false. nm_per_px > 0 is
  // the microscope's scale now (a SELECT command's): the target is expected at the set's
  // recorded nm/px over it times the pattern's size, and tracking after the new search starts
  // at that scale instead of 1. A new set or a new expected scale means the target looks
  // different: it is searched again. A scale outside the tracked range (0.7..1.45: the ROI
  // cannot hold the target, or the pattern is too coarse for it) is refused too, returns false:
  // it used to be clamped to the range's end and acknowledged, so the target was searched at a
  // size it does not have while the controller believed the step taken.
  bool select_pattern_set(std::uint8_t set, double nm_per_px = 0) noexcept;
  // Whether select_pattern_set(set, nm_per_px) would take it (nothing changes).
  bool selectable(std::uint8_t set, double nm_per_px) const noexcept;
  std::size_t pattern_set_count() const noexcept;
  // The noise floors measured at setup (the best score pure noise reaches, mean + 5 sd over
  // 8 noise frames) for the tracking ROI and the full-field search: never TRACKING at or
  // below them.
  float noise_floor_roi(std::size_t set) const noexcept;
  float noise_floor_field(std::size_t set) const noexcept;
  std::uint8_t pattern_set() const noexcept;
  // A set's rotational self-similarity measured at setup (pattern_symmetry.hpp); set out of
  // range: order 1.
  PatternSymmetry symmetry(std::size_t set) const noexcept;
  double nm_per_px() const noexcept;
  // Forget the target and search the field again. `commanded` (a controller's REACQUIRE, a
  // SELECT of a new look): the first pose the search gives carries reason 32 and is at most
  // UNCERTAIN, so the pose stream shows the command took effect whatever frame ran it;
  // sempose's own re-search (look-alike, TrackingStep) passes false and marks it itself.
  void request_reacquire(bool commanded = true) noexcept;
  // Setup: where the target is at start (field pixels, radius > 0). The start searches keep to
  // this circle until the target is first reported TRACKING; after that they cover the field as
  // before. A copy of the object elsewhere in the field scores as well as the target (a twin,
  // the background a target was cut from): only its place tells them apart.
  void set_start_area(double x_px, double y_px, double radius_px) noexcept;
  // Learned appearance (tracker.appearance; README: Learned appearance). Not RT: folds a batch
  // of good frames the RT side completed into the model, checks it against the recorded
  // pattern and, when it passes, builds the bank with the learned support and swaps it in
  // (double buffer + atomic index; update() picks it up at its next frame without a lock or an
  // allocation). Offline callers run it between frames; `sempose run` runs it on a worker
  // thread (start_appearance_worker). True when a new bank was published.
  bool maintain_appearance();
  // Starts a non-RT thread calling maintain_appearance() every 20 ms until the tracker is
  // destroyed (it inherits the caller's CPU placement and scheduling). No-op when off. Fails
  // naming the thread limit when the thread cannot be created (it was a bare "Resource
  // temporarily unavailable" from std::thread, found probing under `prlimit --nproc`).
  rt::Status start_appearance_worker();
  struct AppearanceStatus {
    std::uint32_t accepted = 0;  // updates swapped in
    std::uint32_t rejected = 0;  // batches the drift or support check refused
    std::uint32_t deferred = 0;  // swaps skipped because update() had not picked up the last one
    double support_fraction = 1.0;  // of the pattern circle, the last accepted update's
    std::uint32_t template_updates = 0;  // batches that entered the refined template (refine_template)
    double template_weight = 0;          // the observations' mean weight in the last refined template
  };
  AppearanceStatus appearance_status() const noexcept;
  // The detector's τ measured from the frames (tracker.measure_detector_tau with no
  // tracker.detector_tau_ns; line_correlation.hpp): the noise's correlation ρ along the lines,
  // τ in px at the first frame's dwell and in ns (0: a fast detector, ρ below
  // DetectorTauEstimator::kFastRho, or not measuring), over how many ROI frames' worth of accepted
  // frames (settled from kSettledFrames). Readable from any thread.
  // τ told (tracker.detector_tau_ns): the same measurement checks it (measuring unless
  // tracker.measure_detector_tau is off); frames_disagree: the frames' readings disagreed with
  // it (a detector swapped, a dwell changed without the config, or a scan fault: reported);
  // frames_lag_measured: the frames' measured lag is in use in place of the told one (they
  // disagree and read as a low-pass; a scan fault that does not keeps the told lag); patterns_told_overruled: the pattern sets whose own noise disagreed with
  // the lag their dwell_ns implies (a clean crop given a dwell) and whose reading is used.
  // inconsistent: the readings' lag-2 correlation is not a first-order low-pass's (ρ2 − ρ1²,
  // lag2_excess, above DetectorTauEstimator's kLag2 bound: dropped lines): no lag is
  // taken out and tau_px / tau_ns read 0 (rho is the lag-1 reading as it stands).
  struct DetectorTauStatus {
    bool measuring = false;
    double rho = 0, tau_px = 0, tau_ns = 0, frames = 0;
    double told_tau_ns = 0;
    bool frames_disagree = false;
    bool frames_lag_measured = false;
    int patterns_told_overruled = 0;
    double lag2_excess = 0;
    bool inconsistent = false;
    // Frames whose lag against the pattern was beyond what sempose corrects (Tracker::
    // kMaxCorrectedLagPx: their poses UNCERTAIN), and the largest such lag (px).
    double beyond_frames = 0, beyond_max_px = 0;
  };
  DetectorTauStatus detector_tau_status() const noexcept;
  // The largest lag between the frames' detector low-pass and the pattern's (mean delay, px
  // along the line) whose correction is measured: pose_envelope_probe detector_tau_* to τ 4 px
  // (lags read 3.45–3.96 px there, the poses' mean x error up to 1.3 px); at 6–12 px it erred by
  // 3–6 px (hostile round 12). 4.5: a reading's noise at 4 px stays below it. A frame beyond it
  // is UNCERTAIN.
  static constexpr double kMaxCorrectedLagPx = 4.5;
  // The shortest pixel dwell at which the frames' detector lag against the active pattern stays
  // within kFloorLagShare × kMaxCorrectedLagPx, from the τ in use (told or measured) — the
  // governor's floor for this target's ROIs (0: no detector lag known). Updated every frame;
  // readable from any thread.
  std::uint32_t shortest_correctable_dwell_ns() const noexcept;
  static constexpr double kFloorLagShare = 0.8;
  // Bank + spectra + FFT buffers, bytes (printed at start).
  std::size_t memory_bytes() const noexcept;
  // Setup (not RT): how much another target's patterns look like this one's — the best ZNCC
  // of any of its recorded patterns against any of ours, over our turned copies (every 2°)
  // and shifts of up to ±4 px. Targets at or above kAlike are look-alikes: a start search of
  // one does not take the object the other holds (two identical tips). Different targets that
  // overlap (a lamella between a gripper's jaws) stay below it and are searched as before.
  // Measured on the simulator's scenes: one pattern twice 1.0, two needle tips recorded apart
  // (30° turned) 0.93, two procedural lamellae 0.84, a gripper against a lamella 0.54.
  double likeness(const Tracker& other) const;
  static constexpr double kAlike = 0.7;

 private:
  struct Impl;
  explicit Tracker(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sempose::pose
