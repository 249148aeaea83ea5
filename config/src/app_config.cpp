#include "sempose/config/app_config.hpp"

#include <algorithm>
#include <memory>
#include <string>

#include "sempose/config/data_path.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {
namespace {

// Checks that need more than one section (run after every section is read).
void cross_check(Section& root, const AppConfig& c) {
  if (c.source == "replay" && c.replay.frames_dir.empty()) {
    root.errors().add(root.mark(), "replay.frames_dir", "required when source is replay");
  }
  const int targets = static_cast<int>(c.targets.size());
  for (int t : c.pipeline.schedule) {
    if (t >= targets) {
      root.errors().add(root.mark(), "pipeline.schedule",
                        std::to_string(t) + " is not a target index (targets: " + std::to_string(targets) +
                            ", allowed [0, " + std::to_string(std::max(0, targets - 1)) + "])");
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

// Simulator textures and backgrounds: relative paths are found as data_path.hpp says; when the
// simulator is the source a missing or unusable file is a config error (key, path, places tried)
// now, before anything starts, not an exception from the scene builder later.
void resolve_sim_data(Section& root, const std::string& config_path, AppConfig& c) {
  auto resolve_one = [&](std::string& path, const std::string& key) {
    std::string resolved, problem;
    if (find_data_file(path, config_path, resolved, problem)) {
      path = resolved;
    } else if (c.source == "sim") {
      root.errors().add(root.mark(), key, path + ": " + problem);
    }
  };
  for (std::size_t i = 0; i < c.sim.targets.size(); ++i) {
    auto& t = c.sim.targets[i];
    if (t.enabled && t.texture.source == "image" && !t.texture.path.empty()) {
      resolve_one(t.texture.path, "sim.targets[" + std::to_string(i) + "].texture.path");
    }
  }
  if (c.sim.background.source == "image" && !c.sim.background.path.empty()) {
    resolve_one(c.sim.background.path, "sim.background.path");
  }
}

}  // namespace

bool load_app_config(const std::string& path, AppConfig& result, std::string& error_text) {
  // Read into a fresh struct (defaults), hand it over at the end.
  auto fresh = std::make_unique<AppConfig>();
  AppConfig& out = *fresh;
  out.path = path;
  Errors errors(path);
  YAML::Node node = load_file(path, errors);
  if (!errors.empty()) {
    error_text = errors.joined();
    result = std::move(out);
    return false;
  }
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
    cross_check(root, out);
    resolve_sim_data(root, path, out);
  }  // root's destructor reports unknown top-level sections
  error_text = errors.joined();
  result = std::move(out);
  return errors.empty();
}

}  // namespace sempose::config
