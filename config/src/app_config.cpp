#include "sempose/config/app_config.hpp"

#include <string>

#include "sempose/config/reader.hpp"

namespace sempose::config {
namespace {

// Checks that need more than one section (run after every section is read).
void cross_check(Section& root, const AppConfig& c) {
  (void)root;
  (void)c;
}

}  // namespace

bool load_app_config(const std::string& path, AppConfig& out, std::string& error_text) {
  out = AppConfig{};
  out.path = path;
  Errors errors(path);
  YAML::Node node = load_file(path, errors);
  if (!errors.empty()) {
    error_text = errors.joined();
    return false;
  }
  {
    Section root(node, "", errors);
    root.opt_choice("source", out.source, {"sim", "replay"});
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
    cross_check(root, out);
  }  // root's destructor reports unknown top-level sections
  error_text = errors.joined();
  return errors.empty();
}

}  // namespace sempose::config
