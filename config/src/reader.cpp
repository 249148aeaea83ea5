#include "sempose/config/reader.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

namespace sempose::config {

void Errors::add(const YAML::Mark& mark, const std::string& key, const std::string& what) {
  std::string where = file_;
  if (!mark.is_null()) where += ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
  messages_.push_back(where + ": " + key + ": " + what);
}

std::string Errors::joined() const {
  std::string out;
  for (const auto& m : messages_) out += m + "\n";
  return out;
}

std::string describe_range(double lo, double hi) {
  auto num = [](double v) {
    if (v <= -1e300 || v >= 1e300 || std::fabs(v) >= 9e18) return std::string(v < 0 ? "-inf" : "inf");
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return std::string(buf);
  };
  return "[" + num(lo) + ", " + num(hi) + "]";
}

Section::Section(YAML::Node node, std::string path, Errors& errors)
    : node_(std::move(node)), path_(std::move(path)), errors_(&errors) {
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) {
    errors_->add(node_.Mark(), path_.empty() ? "(top level)" : path_,
                 "expected a mapping of keys (key: value)");
    node_ = YAML::Node();
  }
}

Section::Section(Section&& o) noexcept
    : node_(std::move(o.node_)), path_(std::move(o.path_)), errors_(o.errors_),
      read_(std::move(o.read_)), finished_(o.finished_) {
  o.finished_ = true;
}

void Section::opt_choice(const char* key, std::string& out, const std::vector<std::string>& allowed) {
  std::string v = out;
  opt(key, v);
  for (const auto& a : allowed) {
    if (a == v) {
      out = v;
      return;
    }
  }
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  errors_->add(present() && node_[key].IsDefined() ? node_[key].Mark() : node_.Mark(), key_path(key),
               "'" + v + "' is not one of: " + list);
}

Section Section::child(const char* key) {
  read_.insert(key);
  YAML::Node n;
  if (present() && node_[key].IsDefined()) n = node_[key];
  return Section(n, key_path(key), *errors_);
}

std::vector<Section> Section::children(const char* key) {
  read_.insert(key);
  std::vector<Section> out;
  if (!present() || !node_[key].IsDefined()) return out;
  const YAML::Node n = node_[key];
  if (!n.IsSequence()) {
    errors_->add(n.Mark(), key_path(key), "expected a list of mappings (- key: value)");
    return out;
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    out.emplace_back(n[i], key_path(key) + "[" + std::to_string(i) + "]", *errors_);
  }
  return out;
}

void Section::error(const char* key, const std::string& what) {
  const bool has_key = present() && node_[key].IsDefined();
  errors_->add(has_key ? node_[key].Mark() : node_.Mark(), key_path(key), what);
}

void Section::finish() {
  if (finished_) return;
  finished_ = true;
  if (!present()) return;
  for (const auto& kv : node_) {
    const std::string k = kv.first.as<std::string>();
    if (read_.count(k) == 0) {
      std::string known;
      for (const auto& r : read_) known += (known.empty() ? "" : ", ") + r;
      errors_->add(kv.first.Mark(), key_path(k.c_str()),
                   "unknown key (known here: " + (known.empty() ? std::string("none") : known) + ")");
    }
  }
}

YAML::Node load_file(const std::string& path, Errors& errors) {
  try {
    YAML::Node root = YAML::LoadFile(path);
    if (!root.IsMap()) {
      errors.add("the top level must be a mapping of sections (sim:, tracker:, ...)");
      return {};
    }
    return root;
  } catch (const YAML::BadFile&) {
    errors.add("cannot open the file (missing or unreadable)");
  } catch (const YAML::Exception& e) {
    errors.add(e.mark, "(syntax)", e.msg);
  }
  return {};
}

}  // namespace sempose::config
