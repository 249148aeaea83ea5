#include "sempose/config/app_config.hpp"

#include <algorithm>
#include <memory>
#include <string>

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

// Pattern files are written relative to the config file's folder.
std::string resolve(const std::string& config_path, const std::string& file) {
  if (file.empty() || file[0] == '/') return file;
  const auto slash = config_path.rfind('/');
  if (slash == std::string::npos) return file;
  return config_path.substr(0, slash + 1) + file;
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
    root.opt_choice("source", out.source, {"sim", "replay"});
    {
      Section s = root.child("scan");
      read_scan(s, out.scan);
    }
    {
      Section s = root.child("sim");
      read_sim(s, out.sim);
    }
    {
      Section s = root.child("replay");
      read_replay(s, out.replay);
    }
    read_targets(root, out.targets);
    for (auto& t : out.targets) {
      for (auto& p : t.pattern_sets) p.file = resolve(path, p.file);
    }
    {
      Section s = root.child("tracker");
      read_tracker(s, out.tracker);
    }
    {
      Section s = root.child("governor");
      read_governor(s, out.governor);
    }
    {
      Section s = root.child("pipeline");
      read_pipeline(s, out.pipeline);
    }
    {
      Section s = root.child("output");
      read_output(s, out.output);
    }
    {
      Section s = root.child("can");
      read_can(s, out.can);
    }
    {
      Section s = root.child("gpio");
      read_gpio(s, out.gpio);
    }
    cross_check(root, out);
  }  // root's destructor reports unknown top-level sections
  error_text = errors.joined();
  result = std::move(out);
  return errors.empty();
}

}  // namespace sempose::config
