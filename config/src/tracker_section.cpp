#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "sempose/config/reader.hpp"
#include "sempose/config/target_name.hpp"
#include "sempose/config/tracker_config.hpp"

namespace sempose::config {

SettingProblem check_tracker_sizes(const TrackerConfig& c, int pattern_px) {
  // Equal sizes leave the pattern one place in the ROI: every pose on the ROI's edge, never a
  // confirmed maximum (found probing: accepted, and TRACKING 6.6 px / 7° off before the walk
  // judged the edge).
  if (c.roi_size_px <= pattern_px) {
    return {"roi_size_px", "the pattern (" + std::to_string(pattern_px) + " px) is " +
                               (c.roi_size_px < pattern_px ? "larger than" : "as large as") + " tracker.roi_size_px (" +
                               std::to_string(c.roi_size_px) +
                               " px); the ROI must be larger than the pattern, by twice the most the target moves in a frame"};
  }
  if (c.search_downsample < 1 || pattern_px / c.search_downsample < 4) {
    return {"search_downsample", std::to_string(c.search_downsample) + " leaves a coarse pattern of " +
                                     std::to_string(c.search_downsample < 1 ? 0 : pattern_px / c.search_downsample) +
                                     " px (pattern " + std::to_string(pattern_px) +
                                     " px); allowed: pattern side / search_downsample >= 4"};
  }
  const double steps = 360.0 / c.angle_step_deg;
  if (!(c.angle_step_deg > 0) || std::fabs(steps - std::round(steps)) > 1e-6) {
    return {"angle_step_deg", std::to_string(c.angle_step_deg) + " does not divide 360"};
  }
  return {};
}

void read_tracker(Section& s, TrackerConfig& c) {
  s.opt("pattern_size_px", c.pattern_size_px, 8, 512);
  s.opt("roi_size_px", c.roi_size_px, 8, 1024);
  // At most 10°: the walk's sub-step fit does not hold across coarser steps, and its poses stay
  // near a bank angle whatever the target's, an error every frame shares, so the stream's own
  // smoothness vouched for them (45°: 12 of 12 TRACKING poses 15-21° off; 12-24°: 1-2 a scene
  // 3.3-4.7 px off; 2-10°: 0, rms 0.5-0.7°; hostile round 12).
  s.opt("angle_step_deg", c.angle_step_deg, 0.25, 10.0);
  s.opt("circular_mask", c.circular_mask);
  s.opt("shape_mask_margin_px", c.shape_mask_margin_px, 0.0, 64.0);
  s.opt("prefilter_passes", c.prefilter_passes, 0, 3);
  {
    Section filter = s.child("filter");
    read_pose_filter(filter, c.filter);
  }
  {
    Section appearance = s.child("appearance");
    read_appearance(appearance, c.appearance);
  }
  {
    Section refine = s.child("refine");
    read_refine(refine, c.refine);
  }
  s.opt("max_angle_steps_per_frame", c.max_angle_steps_per_frame, 1, 180);
  s.opt("recover_sweep_deg", c.recover_sweep_deg, 0.0, 180.0);
  s.opt("recover_step_deg", c.recover_step_deg, 0.25, 90.0);
  s.opt("score_threshold", c.score_threshold, 0.0, 1.0);
  s.opt("psr_threshold", c.psr_threshold, 0.0, 1000.0);
  s.opt("relative_score_threshold", c.relative_score_threshold, 0.0, 1.0);
  s.opt("explained_threshold", c.explained_threshold, 0.0, 1.0);
  s.opt("lost_after_frames", c.lost_after_frames, 1, 1000);
  s.opt("max_false_probability", c.max_false_probability, 0.0, 0.5);
  s.opt("detector_tau_ns", c.detector_tau_ns, 0.0, 1e6);
  s.opt("measure_detector_tau", c.measure_detector_tau);
  s.opt("correct_scan_motion", c.correct_scan_motion);
  s.opt("search_downsample", c.search_downsample, 1, 32);
  s.opt("search_angle_step_deg", c.search_angle_step_deg, 0.25, 90.0);
  s.opt("search_candidates", c.search_candidates, 1, 64);
  s.opt("search_refine_window_deg", c.search_refine_window_deg, 0.0, 180.0);
  s.opt("search_refine_step_deg", c.search_refine_step_deg, 0.25, 90.0);
  // The tracked scale's own range is 0.7–1.45 (the ROI must hold the target).
  s.opt("search_scale_min", c.search_scale_min, 0.7, 1.0);
  s.opt("search_scale_max", c.search_scale_max, 1.0, 1.45);
  s.opt("predict_velocity", c.predict_velocity);
  s.opt("predict_rate_poses", c.predict_rate_poses, 2, 8);
  s.opt("attainable_pattern_noise", c.attainable_pattern_noise);
  s.opt_choice("subpixel", c.subpixel, {"gaussian", "quadratic"});
  s.opt("fit_noise_correction", c.fit_noise_correction);
  s.opt("fit_background_plane", c.fit_background_plane);
  s.opt("sigma_tile_px", c.sigma_tile_px, 1, 64);
  s.opt("sigma_calibration", c.sigma_calibration, 0.0, 100.0);
  s.opt("sigma_noise_factor", c.sigma_noise_factor, 0.0, 100.0);
  s.opt("sigma_angle_factor", c.sigma_angle_factor, 0.01, 100.0);
  s.opt("sigma_scale_factor", c.sigma_scale_factor, 0.01, 100.0);
  s.opt("sigma_floor_px", c.sigma_floor_px, 0.0, 10.0);
  s.opt("sigma_floor_deg", c.sigma_floor_deg, 0.0, 10.0);
  s.opt("sigma_pattern_noise", c.sigma_pattern_noise);
  // Not against a default that stands in for a refused value (`pattern_size_px: 7` was refused,
  // then "the pattern (128 px) is larger than tracker.roi_size_px (96 px)": 128 never written).
  bool sizes_read = true;
  for (const char* key : {"pattern_size_px", "roi_size_px", "search_downsample", "angle_step_deg"})
    sizes_read = sizes_read && !s.errors().refused(s.key_path(key));
  if (const SettingProblem problem = check_tracker_sizes(c, c.pattern_size_px); problem && sizes_read)
    s.error(problem.key.c_str(), problem.message);
}

constexpr std::size_t kMaxPatternSets = 16;  // ipc::kMaxPatternSets (config does not depend on ipc)

void read_targets(Section& root, std::vector<TargetConfig>& out) {
  const std::size_t errors_before_list = root.errors().messages().size();
  std::vector<Section> list = root.children("targets");
  if (list.empty()) {
    // Given but empty: on the simulator the run tracked the simulator's own targets without a
    // word, the opposite of what the line says (found probing); elsewhere it said only "no target".
    if (root.has("targets") && root.errors().messages().size() == errors_before_list)
      root.error("targets", "an empty list: no target to track (list each target with its pattern_sets, or leave "
                            "targets: out to track the simulator's own targets)");
    return;
  }
  out.clear();
  for (std::size_t i = 0; i < list.size(); ++i) {
    auto& t = list[i];
    // An item that is not a mapping was said when read, and an empty one (~) is said as such:
    // both also said "a target needs at least one pattern set", the first without a line.
    if (!t.present()) {
      if (!t.not_a_mapping())
        root.error("targets", "item " + std::to_string(i) + " is empty (~ or nothing): give its name and pattern_sets, or leave the item out");
      out.emplace_back();
      continue;
    }
    TargetConfig tc;
    tc.name = "target" + std::to_string(out.size());
    t.opt("name", tc.name);
    if (!is_target_name(tc.name)) {
      t.error("name", "'" + printable(tc.name) + "' is not a target name (1..64 bytes of UTF-8, no spaces, control or invisible characters)");
    } else {
      for (std::size_t k = 0; k < out.size(); ++k) {
        if (out[k].name == tc.name) t.error("name", "'" + tc.name + "' is already targets[" + std::to_string(k) + "]'s name");
      }
    }
    for (auto& ps : t.children("pattern_sets")) {
      PatternSetConfig p;
      ps.req("file", p.file);
      ps.opt("nm_per_px", p.nm_per_px, 1e-6, 1e9);
      p.nm_per_px_given = ps.has("nm_per_px");
      ps.opt("mask", p.mask);
      ps.opt("dwell_ns", p.dwell_ns, 0u, 100'000'000u);
      tc.pattern_sets.push_back(p);
    }
    if (tc.pattern_sets.empty()) t.error("pattern_sets", "a target needs at least one pattern set ({file, nm_per_px})");
    // An element out of range is named by opt_list and read as 0; the radius's own floor is
    // only judged on a list that read whole (a radius of 1e300 was also "0.000000 below 1 px").
    const std::size_t errors_before = t.errors().messages().size();
    t.opt_list("start_area", tc.start_area, 0.0, 16384.0);
    const bool read_whole = t.errors().messages().size() == errors_before;
    if (!tc.start_area.empty() || t.has("start_area")) {  // given empty, it would be ignored unsaid
      if (tc.start_area.size() != 3) {
        t.error("start_area",
                "expected [x_px, y_px, radius_px] (where the target is at start, in field pixels)");
        tc.start_area.clear();
      } else if (read_whole && !(tc.start_area[2] >= 1.0)) {
        t.error("start_area", "radius_px " + number_text(tc.start_area[2]) + " is outside [1, 16384] px");
        tc.start_area.clear();
      }
    }
    // One set given twice (a copy-paste slip) is its own look-alike: every search finds two
    // hypotheses that score alike, and the tracked share fell 0.55 -> 0.35 (found probing).
    for (std::size_t j = 1; j < tc.pattern_sets.size(); ++j) {
      for (std::size_t k = 0; k < j; ++k) {
        const PatternSetConfig &a = tc.pattern_sets[k], &b = tc.pattern_sets[j];
        std::error_code ec;
        const bool same_file = a.file == b.file || std::filesystem::equivalent(a.file, b.file, ec);
        const bool same_mask = a.mask == b.mask || (!a.mask.empty() && std::filesystem::equivalent(a.mask, b.mask, ec));
        if (same_file && same_mask && a.nm_per_px == b.nm_per_px && a.dwell_ns == b.dwell_ns) {
          t.error("pattern_sets", "set " + std::to_string(j) + " repeats set " + std::to_string(k) + " ('" + b.file +
                                      "', the same nm_per_px, mask and dwell_ns): each would be the other's look-alike; "
                                      "remove one");
          break;
        }
      }
    }
    // SELECT's argument and the heartbeat's pattern_set are 4 bits (ipc::kMaxPatternSets): a
    // 17th set could never be selected or reported.
    if (tc.pattern_sets.size() > kMaxPatternSets) {
      t.error("pattern_sets", std::to_string(tc.pattern_sets.size()) + " pattern sets; at most " +
                                  std::to_string(kMaxPatternSets) + " (the CAN SELECT command and heartbeat carry 4 bits)");
    }
    out.push_back(std::move(tc));
  }
}

}  // namespace sempose::config
