#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "sempose/config/data_path.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/sim_config.hpp"

namespace sempose::config {

std::vector<SimTargetConfig> SimConfig::default_targets() {
  std::vector<SimTargetConfig> t(2);
  // The needle's last 120 px up to its blunt tip, from the real SEM image, shown at 3/4 scale
  // (90x120 px): both tapered edges and the tip's front lie inside a 128 px pattern's circle,
  // so the pattern holds the needle's outline, not its flat interior. The threshold mask keeps
  // the bright needle and drops the trench; the pose point (crop centre) is on the needle axis
  // 34 px behind the tip.
  SimTargetConfig& needle = t[0];
  needle.texture.source = "image";
  needle.texture.path = "data/sem/needle_contact_eb.pgm";  // found as data_path.hpp says
  needle.texture.crop_x = 552;
  needle.texture.crop_y = 430;
  needle.texture.crop_w = 120;
  needle.texture.crop_h = 160;
  needle.texture.mask = "threshold";
  needle.texture.mask_level = 0.5;
  needle.width_px = 90;
  needle.height_px = 120;
  needle.x_px = 512;
  needle.y_px = 384;
  needle.trajectory.kind = "sine";
  needle.trajectory.amplitude_x_px = 60;
  needle.trajectory.amplitude_y_px = 30;
  needle.trajectory.amplitude_phi_deg = 10;
  needle.trajectory.period_s = 10;
  // A two-jaw gripper, off by default (enable it for two-target runs).
  SimTargetConfig& gripper = t[1];
  gripper.enabled = false;
  gripper.texture.source = "gripper";
  gripper.width_px = 160;
  gripper.height_px = 120;
  gripper.brightness = 0.9;
  gripper.x_px = 800;
  gripper.y_px = 560;
  gripper.phi_deg = 90;
  return t;
}

namespace {

void read_crop(Section& s, std::int32_t& x, std::int32_t& y, std::int32_t& w, std::int32_t& h) {
  std::vector<std::int32_t> crop;
  s.opt_list("crop", crop, std::int32_t{0}, std::int32_t{16384});
  // Given empty, or of no width or height, it used to crop nothing (the whole image) unsaid.
  if (crop.empty() && !s.has("crop")) return;
  if (crop.size() != 4) {
    s.error("crop", "expected [x, y, w, h] (4 numbers), got " + std::to_string(crop.size()));
    return;
  }
  if (crop[2] < 1 || crop[3] < 1) {
    s.error("crop", "w and h must be at least 1 (got " + std::to_string(crop[2]) + " x " + std::to_string(crop[3]) +
                        "); leave crop out for the whole image");
    return;
  }
  x = crop[0], y = crop[1], w = crop[2], h = crop[3];
}

void read_trajectory(Section& s, TrajectoryConfig& t) {
  const std::size_t errors_before = s.errors().messages().size();
  s.opt_choice("kind", t.kind, {"static", "linear", "sine", "steps", "jumps", "spin", "random_walk"});
  const bool kind_read = s.errors().messages().size() == errors_before;
  s.opt("vx_px_s", t.vx_px_s, -1e5, 1e5);
  s.opt("vy_px_s", t.vy_px_s, -1e5, 1e5);
  s.opt("omega_deg_s", t.omega_deg_s, -1e5, 1e5);
  s.opt("amplitude_x_px", t.amplitude_x_px, -16384.0, 16384.0);
  s.opt("amplitude_y_px", t.amplitude_y_px, -16384.0, 16384.0);
  s.opt("amplitude_phi_deg", t.amplitude_phi_deg, -180.0, 180.0);
  s.opt("period_s", t.period_s, 1e-3, 1e6);
  s.opt("steps", t.steps, 1, 1000);
  s.opt("sigma_px_per_sqrt_s", t.sigma_px_per_sqrt_s, 0.0, 1e4);
  s.opt("sigma_deg_per_sqrt_s", t.sigma_deg_per_sqrt_s, 0.0, 1e4);
  s.opt("knot_s", t.knot_s, 1e-4, 100.0);
  s.opt("margin_px", t.margin_px, 0.0, 8192.0);
  t.margin_given = s.has("margin_px");
  // A key its kind does not use was read and dropped (found probing: `{vx_px_s: 100}` without
  // a kind recorded a still target; `vx_px_s` under `kind: sine` did nothing). Which kind reads
  // which key: hal/scan/trajectory.cpp.
  struct Uses {
    const char* key;
    std::vector<std::string> kinds;
  };
  static const Uses uses[] = {{"vx_px_s", {"linear"}},
                              {"vy_px_s", {"linear"}},
                              {"omega_deg_s", {"linear", "spin"}},
                              {"amplitude_x_px", {"sine", "steps"}},
                              {"amplitude_y_px", {"sine", "steps"}},
                              {"amplitude_phi_deg", {"sine", "steps", "jumps"}},
                              {"period_s", {"sine", "steps", "jumps"}},
                              {"steps", {"steps"}},
                              {"sigma_px_per_sqrt_s", {"random_walk"}},
                              {"sigma_deg_per_sqrt_s", {"random_walk"}},
                              {"knot_s", {"random_walk"}},
                              {"margin_px", {"linear", "jumps", "random_walk"}}};
  for (const Uses& u : uses) {
    // A kind refused is already named: its keys are not judged against the default it left.
    if (!kind_read || !s.has(u.key) || std::find(u.kinds.begin(), u.kinds.end(), t.kind) != u.kinds.end()) continue;
    std::string kinds;
    for (const std::string& k : u.kinds) kinds += (kinds.empty() ? "" : ", ") + k;
    s.error(u.key, std::string("applies to kind ") + kinds + " only, not '" + t.kind + "'" +
                       (s.has("kind") ? "" : " (no kind given: the target's default)"));
  }
}

// A TimeProfile as a mapping {from, to, start_s, ramp_s, amplitude, period_s}; `value` alone
// sets from = to (a constant). Values (and value ± amplitude) must stay within [lo, hi].
void read_profile(Section& parent, const char* key, TimeProfile& p, double lo, double hi) {
  Section s = parent.child(key);
  if (!s.present()) return;
  double value = p.from;
  // `value` is a constant: with from or to beside it one of them was silently not used.
  if (s.has("value") && (s.has("from") || s.has("to")))
    s.error("value", "value (a constant) and from / to (a change) exclude each other: give one of them");
  if (s.has("value")) {
    s.opt("value", value, lo, hi);
    p.from = p.to = value;
  } else {
    s.opt("value", value, lo, hi);
  }
  s.opt("from", p.from, lo, hi);
  s.opt("to", p.to, lo, hi);
  if (!s.has("to") && s.has("from") && !s.has("value")) p.to = p.from;
  // start_s and ramp_s shape the change from -> to; beside a constant they were read and
  // dropped without a word (found probing: the frames byte for byte those without them).
  const bool constant = s.has("value") || (s.has("from") && !s.has("to"));
  for (const char* shaping : {"start_s", "ramp_s"}) {
    if (constant && s.has(shaping)) {
      s.error(shaping, std::string("shapes a change from -> to; ") +
                           (s.has("value") ? "value is a constant" : "from without to is a constant") +
                           ": give from and to, or drop " + shaping);
    }
  }
  s.opt("start_s", p.start_s, 0.0, 1e6);
  s.opt("ramp_s", p.ramp_s, 0.0, 1e6);
  s.opt("amplitude", p.amplitude, -(hi - lo), hi - lo);
  s.opt("period_s", p.period_s, 1e-3, 1e6);
  const double a = std::fabs(p.amplitude);
  if (std::min(p.from, p.to) - a < lo || std::max(p.from, p.to) + a > hi) {
    s.error("amplitude", "from/to ± amplitude leaves the allowed range " + describe_range(lo, hi));
  }
}

void read_target(Section& s, SimTargetConfig& t) {
  s.opt("enabled", t.enabled);
  Section tex = s.child("texture");
  if (tex.has("path") && !tex.has("source")) t.texture.source = "image";
  tex.opt_choice("source", t.texture.source, {"image", "gripper", "lamella"});
  tex.opt("path", t.texture.path);
  read_crop(tex, t.texture.crop_x, t.texture.crop_y, t.texture.crop_w, t.texture.crop_h);
  tex.opt_choice("mask", t.texture.mask, {"full", "threshold", "threshold_all"});
  tex.opt("mask_level", t.texture.mask_level, 0.0, 1.0);
  if (t.texture.source == "image" && t.texture.path.empty()) {
    tex.error("path", "texture source 'image' needs a PGM path");
  }
  // A path, crop or mask beside a procedural source was read and never used.
  for (const char* key : {"path", "crop", "mask", "mask_level"}) {
    if (t.texture.source != "image" && tex.has(key))
      tex.error(key, "applies to texture source 'image' only, not '" + t.texture.source + "'");
  }
  std::vector<std::int32_t> size;
  s.opt_list("size", size, std::int32_t{4}, std::int32_t{4096});
  if (!size.empty() || s.has("size")) {  // given empty, it kept the default unsaid
    if (size.size() != 2) s.error("size", "expected [width_px, height_px]");
    else t.width_px = size[0], t.height_px = size[1];
  }
  s.opt("brightness", t.brightness, 0.0, 4.0);
  std::vector<double> start;
  s.opt_list("start", start, -16384.0, 16384.0);
  if (!start.empty() || s.has("start")) {  // given empty, it kept the default unsaid
    if (start.size() != 3) s.error("start", "expected [x_px, y_px, phi_deg]");
    else t.x_px = start[0], t.y_px = start[1], t.phi_deg = start[2];
  }
  Section traj = s.child("trajectory");
  read_trajectory(traj, t.trajectory);
  read_profile(s, "scale", t.scale, 0.25, 4.0);
  read_profile(s, "jaws", t.jaws, -64.0, 64.0);
  if (!t.jaws.is_constant() || t.jaws.from != 0) {
    if (t.texture.source != "gripper") s.error("jaws", "jaws move only on a procedural gripper (texture source 'gripper')");
  }
}

}  // namespace

void read_sim(Section& s, SimConfig& c) {
  s.opt("seed", c.seed);
  s.opt_choice("clock", c.clock, {"real", "virtual"});
  s.opt("noise", c.noise);
  s.opt("use_shape_masks", c.use_shape_masks);
  s.opt("beam_current_pa", c.beam_current_pa, 0.01, 1e5);
  s.opt("yield", c.yield, 1e-4, 10.0);
  s.opt("detector_gain_shape", c.detector_gain_shape, 0.2, 1000.0);
  s.opt("read_noise_e", c.read_noise_e, 0.0, 1e4);
  s.opt("output_offset", c.output_offset, 0.0, 1.0);
  s.opt("output_white", c.output_white, 0.01, 1.0);
  s.opt("psf_sigma_px", c.psf_sigma_px, 0.0, 16.0);
  s.opt("line_jitter_px", c.line_jitter_px, 0.0, 32.0);
  s.opt("beam_lag_px", c.beam_lag_px, 0.0, 64.0);
  s.opt("beam_lag_len_px", c.beam_lag_len_px, 0.1, 256.0);
  if (s.has("drift")) {
    c.drift.clear();
    std::vector<Section> terms = s.children("drift");
    // Every term is summed for every scanned line on the RT path: 200,000 terms were accepted
    // (sim took 18 s for two 320x240 frames). A few slow sines model a stage's drift.
    if (terms.size() > kMaxDriftTerms) {
      s.error("drift", std::to_string(terms.size()) + " terms; at most " + std::to_string(kMaxDriftTerms) + " are allowed");
    }
    for (Section& d : terms) {
      DriftTerm term;
      d.opt("amplitude_px", term.amplitude_px, 0.0, 1000.0);
      d.opt("period_s", term.period_s, 1e-3, 1e6);
      d.opt("direction_deg", term.direction_deg, -360.0, 360.0);
      d.opt("phase_deg", term.phase_deg, -360.0, 360.0);
      c.drift.push_back(term);
    }
  } else {
    s.children("drift");  // mark as known
  }
  s.opt("brightness_drift", c.brightness_drift, 0.0, 0.9);
  s.opt("brightness_drift_period_s", c.brightness_drift_period_s, 1e-3, 1e6);
  {
    Section ch = s.child("charging");
    read_profile(ch, "gain", c.charging_gain, 0.0, 10.0);
    read_profile(ch, "offset", c.charging_offset, -1.0, 1.0);
  }
  read_profile(s, "defocus_px", c.defocus_px, 0.0, 8.0);
  s.opt("detector_tau_ns", c.detector_tau_ns, 0.0, 1e6);
  Section bg = s.child("background");
  bg.opt_choice("source", c.background.source, {"procedural", "image"});
  bg.opt("path", c.background.path);
  read_crop(bg, c.background.crop_x, c.background.crop_y, c.background.crop_w, c.background.crop_h);
  bg.opt("mean", c.background.mean, 0.0, 1.0);
  bg.opt("contrast", c.background.contrast, 0.0, 1.0);
  bg.opt("grain_px", c.background.grain_px, 0.5, 64.0);
  if (c.background.source == "image" && c.background.path.empty()) {
    bg.error("path", "background source 'image' needs a PGM path");
  }
  // Read and never used (found probing: an image background with mean/contrast/grain_px gave
  // the same frames byte for byte).
  for (const char* key : {"mean", "contrast", "grain_px"}) {
    if (c.background.source == "image" && bg.has(key)) bg.error(key, "applies to background source 'procedural' only, not 'image'");
  }
  for (const char* key : {"path", "crop"}) {
    if (c.background.source != "image" && bg.has(key)) bg.error(key, "applies to background source 'image' only, not '" + c.background.source + "'");
  }
  if (s.has("targets")) {
    std::vector<Section> list = s.children("targets");
    if (list.size() > 4) s.error("targets", std::to_string(list.size()) + " targets; at most 4 are allowed");
    c.targets.clear();
    for (std::size_t i = 0; i < list.size(); ++i) {
      Section& ts = list[i];
      // An empty item (`- ~`) added a default target unsaid.
      if (!ts.present())
        s.error("targets", "item " + std::to_string(i) + " is empty (~ or nothing): give its keys, or leave the item out");
      SimTargetConfig t;  // a listed target starts from a static, enabled, untextured default
      t.texture.source = "lamella";
      read_target(ts, t);
      c.targets.push_back(t);
    }
  } else {
    s.children("targets");
  }
}

void read_replay(Section& s, ReplayConfig& c) {
  s.opt("frames_dir", c.frames_dir);
  s.opt("loop", c.loop);
  s.opt_choice("clock", c.clock, {"virtual", "real"});
}

void resolve_sim_data(Section& root, const std::string& config_path, SimConfig& sim, bool required) {
  auto resolve_one = [&](std::string& path, const std::string& key) {
    std::string resolved, problem;
    if (find_data_file(path, config_path, resolved, problem)) {
      path = resolved;
    } else if (required) {
      root.error_at(key, path + ": " + problem);
    }
  };
  for (std::size_t i = 0; i < sim.targets.size(); ++i) {
    auto& t = sim.targets[i];
    if (t.enabled && t.texture.source == "image" && !t.texture.path.empty()) {
      resolve_one(t.texture.path, "sim.targets[" + std::to_string(i) + "].texture.path");
    }
  }
  if (sim.background.source == "image" && !sim.background.path.empty()) resolve_one(sim.background.path, "sim.background.path");
}

void check_sim_room(Section& root, const SimConfig& sim, int field_w, int field_h) {
  // The bounds are [margin, side - 1 - margin] (hal/scan/trajectory.cpp clamps the margin to
  // half the side): at half the shorter side or more the target cannot move on that axis, and a
  // random walk recorded a still target without a word (found probing: 5000 on 320x240).
  const double room = (std::min(field_w, field_h) - 1) / 2.0;
  for (std::size_t i = 0; i < sim.targets.size(); ++i) {
    const TrajectoryConfig& t = sim.targets[i].trajectory;
    if (!sim.targets[i].enabled || !t.margin_given || t.margin_px < room) continue;
    root.error_at("sim.targets[" + std::to_string(i) + "].trajectory.margin_px",
                  number_text(t.margin_px) + " px leaves the target no room to move in the " + std::to_string(field_w) + "x" +
                      std::to_string(field_h) + " field (below " + number_text(room) + ", half its shorter side)");
  }
}

}  // namespace sempose::config
