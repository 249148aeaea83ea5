#include "sempose/pipeline/tracker_setup.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>

#include "sempose/hal/pgm.hpp"
#include "sempose/ipc/protocol.hpp"
#include "sempose/hal/sim_source.hpp"
#include "sempose/pipeline/pose_input.hpp"
#include "sempose/pose/tracker.hpp"

namespace sempose::pipeline {

TrackerSetup::TrackerSetup() = default;
TrackerSetup::~TrackerSetup() = default;
TrackerSetup::TrackerSetup(TrackerSetup&&) noexcept = default;
TrackerSetup& TrackerSetup::operator=(TrackerSetup&&) noexcept = default;

namespace {
// "target T pattern set K looks the same turned by 180° (self-NCC 0.82, ...)": empty for order 1.
std::string symmetry_note(const pose::Tracker& tracker, const std::string& name, std::size_t set) {
  const pose::PatternSymmetry sym = tracker.symmetry(set);
  if (sym.order <= 1) return {};
  const std::size_t k = static_cast<std::size_t>(
      std::find(pose::PatternSymmetry::kOrders.begin(), pose::PatternSymmetry::kOrders.end(), sym.order) -
      pose::PatternSymmetry::kOrders.begin());
  char b[320];
  std::snprintf(b, sizeof b,
                "target %s pattern set %zu looks the same turned by %.0f deg (self-NCC %.2f, a pose 3 px / 10 deg off "
                "scores %.2f): its angle is known modulo %.0f deg, the turn about (%+.1f, %+.1f) px from the pattern's centre",
                name.c_str(), set, 360.0 / sym.order, sym.self_score[k], sym.same_look_score, 360.0 / sym.order,
                sym.centre_dx_px, sym.centre_dy_px);
  return b;
}

// The simulator's pattern: recorded at a slow dwell, averaged over 10 scans (as in the paper).
constexpr int kPatternFrames = 10;
constexpr double kSimNmPerPx = 40.0;  // the paper's scale (~40 nm per pixel)
}  // namespace

rt::Status load_pattern_set(const config::PatternSetConfig& ps, pose::PatternSet& out) {
  std::string error;
  hal::Image image, mask;
  if (!hal::try_read_pgm(ps.file, image, error)) return rt::Status::failure("pattern file '" + ps.file + "': " + error);
  if (!ps.mask.empty() && !hal::try_read_pgm(ps.mask, mask, error))
    return rt::Status::failure("mask file '" + ps.mask + "': " + error);
  out.image = to_pattern_image(std::move(image));
  out.mask = to_pattern_image(std::move(mask));
  out.nm_per_px = ps.nm_per_px;
  out.dwell_ns = ps.dwell_ns;
  return rt::Status::success();
}

rt::Status make_trackers(const config::AppConfig& cfg, const hal::ScanLimits& limits, TrackerSetup& out) {
  // The tracking ROI must be a scan the source accepts (config checks the sim's limits; a
  // replay's field comes from its frames): otherwise the run would stall after one pose. The
  // tracker's ROI is square, min(roi_size_px, field_w, field_h) a side (pose::EngineSizes): a
  // 512 ROI on a 320x240 field is 240x240, not the whole field (it passed as 320x240 and the
  // run stalled with thousands of refused scans).
  const int roi_w = std::min({cfg.tracker.roi_size_px, limits.field_w, limits.field_h});
  const int roi_h = roi_w;
  if (!(roi_w == limits.field_w && roi_h == limits.field_h) && (roi_w > limits.max_roi_w || roi_h > limits.max_roi_h)) {
    return rt::Status::failure(cfg.path + ": tracker.roi_size_px: " + std::to_string(cfg.tracker.roi_size_px) +
                               " gives a " + std::to_string(roi_w) + "x" + std::to_string(roi_h) +
                               " ROI, larger than the source's largest ROI " + std::to_string(limits.max_roi_w) + "x" +
                               std::to_string(limits.max_roi_h) + " (scan.max_roi_w/h)");
  }
  std::vector<std::vector<pose::PatternSet>> per_target;
  std::vector<std::string> set_files;  // per target, for a refusal: each set's pattern and mask
  if (!cfg.targets.empty()) {
    for (const auto& t : cfg.targets) {
      std::vector<pose::PatternSet> sets;
      std::string origins, files;
      for (std::size_t k = 0; k < t.pattern_sets.size(); ++k) {
        const auto& ps = t.pattern_sets[k];
        pose::PatternSet set;
        const rt::Status loaded = load_pattern_set(ps, set);
        if (!loaded.ok) return rt::Status::failure(cfg.path + ": targets: " + t.name + ": " + loaded.message);
        // Every place in the field must be a position CAN can carry: with nm_per_px 1e6 every
        // pose went out pinned at 134 mm, TRACKING (hostile round 11).
        const int side = std::max(limits.field_w, limits.field_h);
        if (side * ps.nm_per_px > ipc::kXyMaxNm) {
          char numbers[256];  // the figures only: the path and the name can be of any length
          std::snprintf(numbers, sizeof numbers,
                        "%g nm/px puts the %dx%d field's far edge at %.0f nm, beyond the %.0f nm POSE_XY carries (28 bits "
                        "of 1 nm): at most %.0f nm/px for this field",
                        ps.nm_per_px, limits.field_w, limits.field_h, side * ps.nm_per_px, ipc::kXyMaxNm,
                        std::floor(ipc::kXyMaxNm / side));
          return rt::Status::failure(cfg.path + ": targets: " + t.name + ": pattern_sets[" + std::to_string(k) +
                                     "].nm_per_px: " + numbers);
        }
        sets.push_back(std::move(set));
        origins += (origins.empty() ? "" : ", ") + ps.file;
        files += (files.empty() ? "" : "; ") + ("set " + std::to_string(k) + " " + ps.file) +
                 (ps.mask.empty() ? "" : ", mask " + ps.mask);
      }
      set_files.push_back(files);
      per_target.push_back(std::move(sets));
      out.names.push_back(t.name);
      out.pattern_origins.push_back(origins);
    }
  } else if (cfg.source == "sim") {
    const std::uint32_t dwell = std::clamp<std::uint32_t>(2'000, limits.min_dwell_ns, limits.max_dwell_ns);
    for (std::size_t i = 0; i < cfg.sim.targets.size(); ++i) {
      if (!cfg.sim.targets[i].enabled) continue;
      pose::PatternSet set;
      try {
        set.image = to_pattern_image(hal::render_sim_pattern(cfg.sim, limits, static_cast<int>(i),
                                                             cfg.tracker.pattern_size_px, kPatternFrames, dwell,
                                                             cfg.sim.seed + 1000 + i));
        // The simulator knows the target's outline: its shape mask, as an operator would draw
        // it — opt-in (sim.use_shape_masks), it costs robustness at a few e⁻/px (README).
        if (cfg.sim.use_shape_masks)
          set.mask = to_pattern_image(
              hal::render_sim_pattern_mask(cfg.sim, limits, static_cast<int>(i), cfg.tracker.pattern_size_px));
      } catch (const std::exception& e) {
        return rt::Status::failure(cfg.path + ": sim.targets[" + std::to_string(i) + "]: cannot record its pattern: " +
                                   e.what());
      }
      set.nm_per_px = kSimNmPerPx;
      set.dwell_ns = dwell;
      per_target.push_back({std::move(set)});
      out.names.push_back("sim" + std::to_string(i));
      out.pattern_origins.push_back("recorded from simulator target " + std::to_string(i));
      std::string recorded = "its pattern recorded from simulator target " + std::to_string(i);
      // A pattern the tracker refuses as flat is, on the simulator, most often a clipped scene:
      // the user wrote no pattern, so the keys that clip it are named (found probing:
      // `sim.output_offset: 1` said only "pattern set 0: the pattern is flat").
      if (cfg.sim.output_offset + cfg.sim.output_white > 1.0) {
        char clip[200];
        std::snprintf(clip, sizeof clip,
                      "; sim.output_offset %g + sim.output_white %g = %g of full scale: the simulated detector clips "
                      "the bright parts",
                      cfg.sim.output_offset, cfg.sim.output_white, cfg.sim.output_offset + cfg.sim.output_white);
        recorded += clip;
      }
      set_files.push_back(recorded);
    }
  }
  if (per_target.empty()) {
    return rt::Status::failure(cfg.path + ": targets: no target to track (add a targets: list with pattern files" +
                               std::string(cfg.source == "sim" ? ", or enable a sim target)" : ")"));
  }
  // The detector's time constant: the config's, or on the simulated SEM its simulated
  // detector's (what a calibration of that detector would measure).
  config::TrackerConfig tracker_cfg = cfg.tracker;
  if (!(tracker_cfg.detector_tau_ns > 0) && cfg.source == "sim") tracker_cfg.detector_tau_ns = cfg.sim.detector_tau_ns;
  // Learned appearance is an option measured worse than the recorded pattern, and it can drag
  // the poses it reports TRACKING: a needle spinning 400°/s while its scale ramps 1 -> 0.7, 7 poses
  // 3-5.5 px off at frames_per_update 4, 6 at 12, the defaults' RMS 1.3 px against 0.3 without it
  // (hostile round 12). Said at setup, so no lab closes a loop on it unaware.
  if (tracker_cfg.appearance.enabled) {
    out.warnings.push_back("tracker.appearance.enabled: learned appearance is experimental: measured less accurate than "
                           "the recorded pattern, and it can drag TRACKING poses 3-5 px off while the target's scale "
                           "changes (README: Known limitations); not for closing a loop on");
  }
  for (std::size_t i = 0; i < per_target.size(); ++i) {
    rt::Status st;
    auto tracker = pose::Tracker::create(tracker_cfg, std::move(per_target[i]), limits, st);
    // The config and the pattern files named: the tracker's refusal (a pattern not square, flat,
    // larger than the ROI, a mask of another size) knows only the set's index (found probing:
    // "target t: tracker: pattern set 0: the pattern is 128x64; patterns must be square").
    if (!tracker) {
      return rt::Status::failure(cfg.path + ": target " + out.names[i] + ": " + st.message + " (" + set_files[i] + ")");
    }
    if (i < cfg.targets.size() && cfg.targets[i].start_area.size() == 3) {
      const auto& a = cfg.targets[i].start_area;
      // The field is the source's (a recording's frames set it): checked here, not in the config.
      if (a[0] >= limits.field_w || a[1] >= limits.field_h) {
        return rt::Status::failure(
            cfg.path + ": targets[" + std::to_string(i) + "].start_area: centre (" +
            std::to_string(static_cast<int>(a[0])) + ", " + std::to_string(static_cast<int>(a[1])) +
            ") is outside the source's " + std::to_string(limits.field_w) + "x" +
            std::to_string(limits.field_h) + " field");
      }
      tracker->set_start_area(a[0], a[1], a[2]);
    }
    if (!st.message.empty()) out.warnings.push_back("target " + out.names[i] + ": " + st.message);
    out.memory_bytes += tracker->memory_bytes();
    for (std::size_t set = 0; set < tracker->pattern_set_count(); ++set) {
      std::string note = symmetry_note(*tracker, out.names[i], set);
      if (!note.empty()) out.symmetry_notes.push_back(std::move(note));
    }
    // Learned appearance: its rebuilds run on a non-RT worker thread (created here, on the
    // main thread, so it inherits main's placement off the RT cores).
    if (rt::Status started = tracker->start_appearance_worker(); !started)
      return rt::Status::failure("target " + out.names[i] + ": " + started.message);
    out.trackers.push_back(std::move(tracker));
  }
  return rt::Status::success();
}

}  // namespace sempose::pipeline
