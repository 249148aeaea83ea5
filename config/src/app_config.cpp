#include "sempose/config/app_config.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <string>

#include "sempose/config/data_path.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {
namespace {

constexpr int kMaxTrackedTargets = 4;  // hal::kMaxTargets (config does not depend on hal)

// Checks that need more than one section (run after every section is read).
void cross_check(Section& root, const AppConfig& c, OutputCheck outputs, TargetCheck target_check) {
  // A check across keys judges what the file says: a refused value holds the default, and a
  // second error about it would name a value the user never wrote.
  const auto read_as_written = [&root](std::initializer_list<const char*> keys) {
    for (const char* key : keys)
      if (root.errors().refused(key)) return false;
    return true;
  };
  if (c.source == "replay" && c.replay.frames_dir.empty()) {
    root.error_at("replay.frames_dir", "required when source is replay");
  }
  // The simulator's own enabled targets are tracked when no targets: list is given.
  int targets = static_cast<int>(c.targets.size());
  if (targets == 0 && c.source == "sim") {
    targets = static_cast<int>(std::count_if(c.sim.targets.begin(), c.sim.targets.end(),
                                             [](const SimTargetConfig& t) { return t.enabled; }));
  }
  if (targets > kMaxTrackedTargets) {
    root.error_at(c.targets.empty() ? "sim.targets" : "targets",
                  std::to_string(targets) + " targets; at most " +
                      std::to_string(kMaxTrackedTargets) + " can be tracked");
  }
  // A tracking ROI the scan generator refuses would stall after the first pose: the ROI
  // (square, its side clamped to the field's shorter side, as the tracker does:
  // pose::EngineSizes) must fit scan.max_roi_w/h unless it is the whole field, which is
  // always allowed.
  const int roi_w = std::min({c.tracker.roi_size_px, c.scan.field_w, c.scan.field_h});
  const int roi_h = roi_w;
  const bool whole_field = roi_w == c.scan.field_w && roi_h == c.scan.field_h;
  if (c.source == "sim" && !whole_field && (roi_w > c.scan.max_roi_w || roi_h > c.scan.max_roi_h) &&
      read_as_written({"tracker.roi_size_px", "scan.field_w", "scan.field_h", "scan.max_roi_w", "scan.max_roi_h"})) {
    root.error_at("tracker.roi_size_px",
                  std::to_string(c.tracker.roi_size_px) + " gives a " + std::to_string(roi_w) +
                      "x" + std::to_string(roi_h) + " ROI, larger than scan.max_roi_w/h " +
                      std::to_string(c.scan.max_roi_w) + "x" + std::to_string(c.scan.max_roi_h) +
                      " (allowed: at most the scan limits, or the whole field)");
  }
  // A pose rate no ROI scan can reach: the governor's cap on quality lengthening (every target's
  // turn within 1 / min_pose_rate_hz) is then below the shortest dwell and silently off, and the
  // rate the user asked for is never kept (100000 Hz was accepted; found probing). The fastest
  // cycle is every target's ROI at the shortest dwell both the scan and the governor allow. Only a
  // rate the config gives: the default's cap is moot under a long governor.min_dwell_ns, not wrong.
  if (c.governor.enabled && c.governor.min_pose_rate_given && c.source != "replay" && targets > 0 &&
      read_as_written({"tracker.roi_size_px", "scan.field_w", "scan.field_h", "scan.min_dwell_ns", "scan.dwell_step_ns",
                       "scan.line_flyback_ns", "governor.min_dwell_ns", "governor.min_pose_rate_hz"})) {
    const std::uint64_t step = c.scan.step_ns();
    const std::uint64_t shortest = (std::max<std::uint64_t>({c.scan.min_dwell_ns, c.governor.min_dwell_ns, 1}) + step - 1) / step * step;
    const double cycle_ns = static_cast<double>(targets) *
                            static_cast<double>(c.scan.scan_time_ns(roi_w, roi_h, static_cast<std::uint32_t>(shortest)));
    const double fastest_hz = 1e9 / cycle_ns;
    if (c.governor.min_pose_rate_hz > fastest_hz) {
      char text[320];
      std::snprintf(text, sizeof text,
                    "%g Hz a target is more than the ROI scans can give: %d target%s x a %dx%d ROI at the shortest "
                    "dwell %llu ns (scan.min_dwell_ns, governor.min_dwell_ns) plus scan.line_flyback_ns %u a line take "
                    "%.3f ms, %.4g Hz a target at most (allowed: 0.01..%.4g)",
                    c.governor.min_pose_rate_hz, targets, targets == 1 ? "" : "s", roi_w, roi_h,
                    static_cast<unsigned long long>(shortest), static_cast<unsigned>(c.scan.line_flyback_ns), cycle_ns * 1e-6,
                    std::floor(fastest_hz * 1e3) / 1e3, std::floor(fastest_hz * 1e3) / 1e3);
      root.error_at("governor.min_pose_rate_hz", text);
    }
  }
  // A pattern larger than the field cannot be found in it (found probing: a 16x16 field failed
  // in setup with "render_sim_pattern: size 128 does not fit the field", no key named). A
  // replay's field is its frames' size, checked when they are read.
  if (c.source != "replay" && c.tracker.pattern_size_px > std::min(c.scan.field_w, c.scan.field_h) &&
      read_as_written({"tracker.pattern_size_px", "scan.field_w", "scan.field_h"})) {
    root.error_at("tracker.pattern_size_px",
                  std::to_string(c.tracker.pattern_size_px) + " px does not fit the " +
                      std::to_string(c.scan.field_w) + "x" + std::to_string(c.scan.field_h) +
                      " scan field (scan.field_w, scan.field_h): at most " +
                      std::to_string(std::min(c.scan.field_w, c.scan.field_h)));
  }
  // Files: checked for their kind before anything opens them (a directory reads as empty, a
  // FIFO blocks in open(), a device never ends), so a wrong path is a message, not a hang. Not
  // when the caller gives the targets: this section's files are never opened then.
  for (std::size_t i = 0; target_check == TargetCheck::kAgainstTheConfig && i < c.targets.size(); ++i) {
    for (std::size_t j = 0; j < c.targets[i].pattern_sets.size(); ++j) {
      const auto& ps = c.targets[i].pattern_sets[j];
      const std::string key = "targets[" + std::to_string(i) + "].pattern_sets[" + std::to_string(j) + "].";
      if (const std::string why = path_kind_problem(ps.file); !ps.file.empty() && !why.empty()) {
        root.error_at(key + "file", "'" + ps.file + "' is " + why + " (need a PGM file)");
      }
      if (const std::string why = path_kind_problem(ps.mask); !ps.mask.empty() && !why.empty()) {
        root.error_at(key + "mask", "'" + ps.mask + "' is " + why + " (need a PGM file)");
      }
    }
  }
  if (c.source == "replay" && !c.replay.frames_dir.empty()) {
    struct stat st {};
    if (::stat(c.replay.frames_dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
      const std::string why = path_kind_problem(c.replay.frames_dir);
      // A relative folder is the working folder's (patterns are the config's): say where it looked.
      std::error_code ec;
      const std::filesystem::path abs = std::filesystem::absolute(c.replay.frames_dir, ec);
      const std::string looked = std::filesystem::path(c.replay.frames_dir).is_relative() && !ec
                                     ? " (" + abs.lexically_normal().string() + ", from the working folder)"
                                     : "";
      root.error_at("replay.frames_dir", "'" + c.replay.frames_dir + "'" + looked + " is " +
                                             (why.empty() ? std::string("a file") : why) +
                                             " (need a directory of PGM frames)");
    }
  }
  if (c.output.poses_csv == "-") {
    // `sempose run` prints its status lines on stdout; poses there would be mixed into them.
    root.error_at("output.poses_csv",
                  "'-' (standard output) is not supported here: stdout carries the run's status "
                  "lines; name a file");
  }
  if (c.can.interface.empty() && c.can.log_file == "-") {
    // As for the poses: '-' reads as "standard output" elsewhere, but a file named '-' was made
    // in the working folder (found probing).
    root.error_at("can.log_file",
                  "'-' (standard output) is not supported here: stdout carries the run's status "
                  "lines; name a file");
  }
  if (c.output.hist_dir == "-") {
    // A folder named '-' was made in the working folder (found probing).
    root.error_at("output.hist_dir", "'-' (standard output) is not a folder: histograms are files; name a directory");
  }
  if (outputs == OutputCheck::kRefuse) {
    for (const OutputProblem& p : output_problems(c)) root.error_at(p.key, p.what);
  }
  if (c.pipeline.schedule.size() > 16) {  // Pipeline::kMaxSchedule
    root.error_at("pipeline.schedule",
                  std::to_string(c.pipeline.schedule.size()) + " entries; at most 16 are allowed");
  }
  if (target_check == TargetCheck::kLeaveToCaller) return;  // the schedule's targets are the caller's
  std::vector<int> named;  // each index beyond the targets said once, however often it is named
  for (int t : c.pipeline.schedule) {
    if (t >= targets && std::find(named.begin(), named.end(), t) == named.end()) {
      named.push_back(t);
      root.error_at("pipeline.schedule", std::to_string(t) + " is not a target index (targets: " +
                                             std::to_string(targets) + ", allowed [0, " +
                                             std::to_string(std::max(0, targets - 1)) + "])");
    }
  }
  // A target the schedule leaves out is never scanned: no pose, no state, not even LOST, for
  // the whole run (it used to run so, its summary line poses=0).
  for (int t = 0; !c.pipeline.schedule.empty() && t < targets && t <= kMaxTrackedTargets; ++t) {
    if (std::find(c.pipeline.schedule.begin(), c.pipeline.schedule.end(), t) == c.pipeline.schedule.end()) {
      root.error_at("pipeline.schedule",
                    "target " + std::to_string(t) +
                        " is never named: it would never be scanned or reported " +
                        "(name every target at least once, or remove it from the targets)");
    }
  }
}

// Reads one top-level section with its part's reader; the child Section reports its unknown
// keys when it goes out of scope here.
template <typename Config>
void read_section(Section& root, const char* key, void (*reader)(Section&, Config&), Config& out) {
  Section s = root.child(key);
  reader(s, out);
}

// Pattern and mask files are written relative to the config file's folder.
std::string resolve(const std::string& config_path, const std::string& file) {
  if (file.empty() || file[0] == '/') return file;
  const auto slash = config_path.rfind('/');
  if (slash == std::string::npos) return file;
  return config_path.substr(0, slash + 1) + file;
}

}  // namespace

std::vector<OutputProblem> output_problems(const AppConfig& c) {
  std::vector<OutputProblem> out;
  if (const std::string why = output_path_problem(c.output.poses_csv);
      !c.output.poses_csv.empty() && c.output.poses_csv != "-" && !why.empty()) {
    out.push_back(
        {"output.poses_csv", "'" + c.output.poses_csv + "' cannot be written: it is " + why});
  }
  if (const std::string why = output_path_problem(c.can.log_file);
      c.can.interface.empty() && !c.can.log_file.empty() && c.can.log_file != "-" && !why.empty()) {
    out.push_back({"can.log_file", "'" + c.can.log_file + "' cannot be written: it is " + why});
  }
  if (const std::string why = output_dir_problem(c.output.hist_dir);
      !c.output.hist_dir.empty() && !why.empty()) {
    out.push_back(
        {"output.hist_dir", "'" + c.output.hist_dir + "' cannot hold histograms: it is " + why});
  }
  return out;
}

namespace {
bool read_app_config(const std::string& path, YAML::Node node, Errors& errors, AppConfig& result,
                     std::string& error_text, OutputCheck outputs, TargetCheck targets = TargetCheck::kAgainstTheConfig);
}  // namespace

const std::vector<std::string>& app_config_sections() {
  // Kept equal to what read_app_config reads (test: AppConfig.SectionListIsWhatRunReads).
  static const std::vector<std::string> sections = {"source", "scan",   "sim",      "replay",   "comedi", "targets", "tracker",
                                                    "governor", "pipeline", "output", "can", "gpio", "service"};
  return sections;
}

std::vector<KeyInfo> config_keys(const std::string& text) {
  Errors errors("(catalog)");
  AppConfig out;
  std::string ignored;
  read_app_config("(catalog)", load_text(text, errors), errors, out, ignored, OutputCheck::kRefuse);
  return errors.keys();
}

bool load_app_config(const std::string& path, AppConfig& result, std::string& error_text,
                     OutputCheck outputs, TargetCheck targets) {
  Errors errors(path);
  YAML::Node node = load_file(path, errors);
  return read_app_config(path, node, errors, result, error_text, outputs, targets);
}

bool parse_app_config(const std::string& text, const std::string& path, AppConfig& result,
                      std::string& error_text, OutputCheck outputs) {
  Errors errors(path);
  YAML::Node node = load_text(text, errors);
  return read_app_config(path, node, errors, result, error_text, outputs);
}

namespace {
bool read_app_config(const std::string& path, YAML::Node node, Errors& errors, AppConfig& result,
                     std::string& error_text, OutputCheck outputs, TargetCheck targets) {
  // Read into a fresh struct (defaults), hand it over at the end.
  auto fresh = std::make_unique<AppConfig>();
  AppConfig& out = *fresh;
  out.path = path;
  if (!errors.empty()) {
    error_text = errors.joined();
    result = std::move(out);
    return false;
  }
  // yaml-cpp may still throw on shapes nobody expected (a conversion of an odd node): that
  // is a message about the file too, never an escaping exception.
  try {
    {
      Section root(node, "", errors);
      root.opt_choice("source", out.source, {"sim", "replay", "comedi"});
      read_section(root, "scan", read_scan, out.scan);
      read_section(root, "sim", read_sim, out.sim);
      read_section(root, "replay", read_replay, out.replay);
      read_section(root, "comedi", read_comedi, out.comedi);
      read_targets(root, out.targets);
      for (auto& t : out.targets) {
        for (auto& p : t.pattern_sets) {
          p.file = resolve(path, p.file);
          p.mask = resolve(path, p.mask);
        }
      }
      read_section(root, "tracker", read_tracker, out.tracker);
      read_section(root, "governor", read_governor, out.governor);
      read_section(root, "pipeline", read_pipeline, out.pipeline);
      read_section(root, "output", read_output, out.output);
      read_section(root, "can", read_can, out.can);
      read_section(root, "gpio", read_gpio, out.gpio);
      read_section(root, "service", read_service, out.service);
      check_service_against_scan(root, out.service, out.scan, out.governor.initial_dwell_ns);
      check_governor_against_scan(root, out.governor, out.scan);
      cross_check(root, out, outputs, targets);
      // A missing or unusable file is a config error (key, path, places tried) now, before
      // anything starts, not an exception from the scene builder later.
      resolve_sim_data(root, path, out.sim, out.source == "sim");
      if (out.source == "sim") check_sim_room(root, out.sim, out.scan.field_w, out.scan.field_h);
    }  // root's destructor reports unknown top-level sections
  } catch (const std::exception& e) {
    errors.add(std::string("cannot be read: ") + e.what());
  }
  error_text = errors.joined();
  result = std::move(out);
  return errors.empty();
}
}  // namespace

}  // namespace sempose::config
