// Validated reading of one YAML config file. Every problem is collected (not only the first)
// and names the file, line, full key, the value and what is allowed:
//   config/default.yaml:12:3: tracker.score_threshold: 1.7 is outside [0, 1]
// Unknown keys are errors too (a typo must not silently fall back to a default).
// Setup only: allocates and may throw inside yaml-cpp; nothing here runs on an RT thread.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <algorithm>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace sempose::config {

// Every scalar key a reader asked for, with its kind: the catalog the table-driven tests walk
// (NaN/inf for every floating-point key, ...), so a new key is covered without a new test.
enum class KeyKind : std::uint8_t { kFloat, kInteger, kBool, kText };
struct KeyInfo {
  std::string path;  // dotted, with list indices: sim.targets[0].brightness
  KeyKind kind;
};

class Errors {
 public:
  explicit Errors(std::string file) : file_(std::move(file)) {}
  void add(const YAML::Mark& mark, const std::string& key, const std::string& what);
  void add(const std::string& what);
  bool empty() const noexcept { return messages_.empty(); }
  const std::vector<std::string>& messages() const noexcept { return messages_; }
  std::string joined() const;  // one message per line
  const std::string& file() const noexcept { return file_; }
  void note_key(std::string path, KeyKind kind) { keys_.push_back({std::move(path), kind}); }
  const std::vector<KeyInfo>& keys() const noexcept { return keys_; }
  // Whether a message names this key (its dotted path): a check across keys skips a key whose
  // value was refused, which holds the default, not what the file says.
  bool refused(const std::string& path) const {
    return std::find(refused_.begin(), refused_.end(), path) != refused_.end();
  }

 private:
  std::string file_;
  std::vector<std::string> messages_;
  std::vector<std::string> refused_;  // the keys messages_ name
  std::vector<KeyInfo> keys_;
};

// A mapping node with its dotted path. Read keys with opt()/req()/child(); call
// finish() (or let the destructor do it) to report keys nobody read as unknown.
class Section {
 public:
  Section(YAML::Node node, std::string path, Errors& errors);
  ~Section() { finish(); }
  Section(const Section&) = delete;
  Section& operator=(const Section&) = delete;
  Section(Section&&) noexcept;

  bool present() const noexcept { return node_.IsDefined() && !node_.IsNull(); }
  // Given as something other than a mapping (a scalar or a list: already reported when read).
  bool not_a_mapping() const noexcept { return not_a_mapping_; }
  bool has(const char* key) const { return present() && node_[key].IsDefined(); }
  std::string key_path(const char* key) const { return key_path(std::string(key)); }
  // The file's own key, whole: as a C string a key holding a NUL ("sim\0") was named "sim".
  std::string key_path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

  // Optional scalar: leaves `out` (the default) when absent. Numbers are range-checked.
  template <typename T>
  void opt(const char* key, T& out, T lo = lowest<T>(), T hi = highest<T>());
  // Required scalar: an error when absent.
  template <typename T>
  void req(const char* key, T& out, T lo = lowest<T>(), T hi = highest<T>());
  // String restricted to a set of words (e.g. "sim" | "replay").
  void opt_choice(const char* key, std::string& out, const std::vector<std::string>& allowed);
  // Optional list of scalars (e.g. [0, 1]); each element range-checked.
  template <typename T>
  void opt_list(const char* key, std::vector<T>& out, T lo = lowest<T>(), T hi = highest<T>());

  // Nested mapping (may be absent: then present() is false and reads keep defaults).
  Section child(const char* key);
  // Sequence of mappings (e.g. targets: [ {...}, {...} ]).
  std::vector<Section> children(const char* key);

  Errors& errors() noexcept { return *errors_; }
  const YAML::Mark mark() const { return node_.Mark(); }
  void error(const char* key, const std::string& what);
  // An error about a key named by its path below this section ("output.poses_csv",
  // "targets[0].pattern_sets[1].file"), located at that key's line, or at its nearest written
  // parent when the key itself is not in the file (a default). Checks that span sections use it:
  // they used to point at the file's first line.
  void error_at(const std::string& dotted_key, const std::string& what);
  void finish();

 private:
  template <typename T>
  static constexpr T lowest() {
    if constexpr (std::is_arithmetic_v<T>) return std::numeric_limits<T>::lowest();
    else return T{};
  }
  template <typename T>
  static constexpr T highest() {
    if constexpr (std::is_arithmetic_v<T>) return std::numeric_limits<T>::max();
    else return T{};
  }
  template <typename T>
  void read_scalar(const char* key, const YAML::Node& n, T& out, T lo, T hi);
  template <typename T>
  void note(const char* key) {
    KeyKind k = KeyKind::kText;
    if constexpr (std::is_same_v<T, bool>) k = KeyKind::kBool;
    else if constexpr (std::is_floating_point_v<T>) k = KeyKind::kFloat;
    else if constexpr (std::is_integral_v<T>) k = KeyKind::kInteger;
    errors_->note_key(key_path(key), k);
  }

  YAML::Node node_;
  bool not_a_mapping_ = false;
  std::string path_;
  Errors* errors_;
  std::set<std::string> read_;
  bool finished_ = false;
};

// Loads and parses a file; a syntax error or a non-mapping top level goes to errors. The path
// must be a readable regular file of at most kMaxConfigBytes (a directory, FIFO or device is
// refused by name before anything opens it: a FIFO would block, /dev/zero never ends). 1 MiB is
// ~200 times the largest real config; yaml-cpp takes ~240 bytes a node, and a 4 MB list (a
// 2,000,000-entry pipeline.schedule, refused after parsing) took 6.9 s and 945 MB under the
// 16 MiB cap there was (hostile round 12).
constexpr long long kMaxConfigBytes = 1ll << 20;
YAML::Node load_file(const std::string& path, Errors& errors);
YAML::Node load_text(const std::string& text, Errors& errors);  // the same for text in memory

// What kind of file system object a path names, for messages and checks before any open().
// "" when it is a regular file; otherwise e.g. "a directory", "a FIFO", "a character device",
// "missing", "in a missing folder".
std::string path_kind_problem(const std::string& path);
// For an output file: "" when it can be created or written (regular file, missing file in an
// existing writable folder, or a character device such as /dev/null); otherwise why not.
std::string output_path_problem(const std::string& path);
// For an output folder: "" when it is a writable directory or can be created; otherwise why not.
std::string output_dir_problem(const std::string& path);
// A text value (a path, a name) with a control character (bytes 0x00..0x1f, 0x7f, and the
// Unicode ones of unsafe_text.hpp: C1 controls, line separators, invisible and bidirectional
// characters, bytes that are not UTF-8): a newline in a file name breaks every line-oriented
// tool and log, a NUL cut the name short where the C library read it. "" when there is none;
// otherwise a message naming the first one (its escape, bytes and position) with the value
// shown escaped.
std::string control_character_problem(const std::string& value);
// The value with those characters written as escapes (\n, \t, \x01, \u2028): safe in a message.
std::string printable(const std::string& value);
// A message for the terminal or a log: each of its lines printable() and at most ~1 kB, its line
// breaks kept. For text that quotes a file or a path (an exception's what() from a reader): a
// cell holding a terminal escape reached stderr raw, a NUL ended the message mid-quote, and a
// 2 MB cell was a 2 MB line (hostile round 8).
std::string terminal_text(const std::string& message);

// ---- template definitions ----

std::string describe_range(double lo, double hi);
// A number as a message shows it: %g (5000, 1.5, 0.25), not std::to_string's six decimals.
std::string number_text(double v);
// "?" (plain), "!" (quoted) and the core schema's scalar tags: a value read as it is written.
bool tag_is_plain(const std::string& tag);
// "" when a plain tag fits the key's kind, else what the value is tagged as ("a boolean"): a
// `!!bool 96` was read as the number 96, `!!int true` as true (hostile round 8).
std::string tag_kind_problem(const std::string& tag, KeyKind kind);

// Whether a number read as long double is in [lo, hi] once it is the key's type. A floating
// key compares the value it will hold: "0.01" as a long double lies below the double 0.01 (and
// "0.85" above the double 0.85), so a minimum or maximum written exactly as the range prints it
// was refused as outside that range (found probing every key at its edges).
template <typename T>
bool in_range(long double v, T lo, T hi) {
  if constexpr (std::is_floating_point_v<T>) {
    if (v < static_cast<long double>(std::numeric_limits<T>::lowest()) ||
        v > static_cast<long double>(std::numeric_limits<T>::max())) {
      return false;
    }
    const T t = static_cast<T>(v);
    return t >= lo && t <= hi;
  } else {
    return v >= static_cast<long double>(lo) && v <= static_cast<long double>(hi);
  }
}

// "[lo, hi]": an integer key's bounds exactly (describe_range prints |v| >= 9e18 as inf, which
// said "[0, inf]" for a 64-bit seed), a floating key's as describe_range prints them.
template <typename T>
std::string describe_bounds(T lo, T hi) {
  if constexpr (std::is_integral_v<T>) {
    return "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  } else {
    return describe_range(static_cast<double>(lo), static_cast<double>(hi));
  }
}

template <typename T>
void Section::read_scalar(const char* key, const YAML::Node& n, T& out, T lo, T hi) {
  const std::string shown = n.IsScalar() ? n.Scalar() : std::string("(a ") +
                            (n.IsSequence() ? "list" : n.IsMap() ? "mapping" : "null") + ")";
  if (!n.IsScalar()) {
    errors_->add(n.Mark(), key_path(key), shown + " is not a single value");
    return;
  }
  // A tag changes what a value means (`!!binary aGVsbG8=` is "hello"), yet it was dropped and
  // the text read as it stands: only the plain types are accepted.
  if (const std::string& tag = n.Tag(); !tag_is_plain(tag)) {
    errors_->add(n.Mark(), key_path(key), "'" + shown + "' carries the tag '" + tag +
                                              "'; only plain values (or !!str, !!int, !!float, !!bool) are read");
    return;
  }
  if constexpr (std::is_arithmetic_v<T>) {
    const KeyKind kind = std::is_same_v<T, bool> ? KeyKind::kBool : std::is_floating_point_v<T> ? KeyKind::kFloat : KeyKind::kInteger;
    if (const std::string tagged = tag_kind_problem(n.Tag(), kind); !tagged.empty()) {
      errors_->add(n.Mark(), key_path(key), "'" + shown + "' is tagged as " + tagged + ", but the key takes " +
                                                (kind == KeyKind::kBool ? "true or false" : "a number"));
      return;
    }
  }
  if constexpr (std::is_same_v<T, bool>) {
    bool v = false;
    if (!YAML::convert<bool>::decode(n, v)) {
      errors_->add(n.Mark(), key_path(key), "'" + shown + "' is not a boolean (true/false)");
      return;
    }
    out = v;
  } else if constexpr (std::is_arithmetic_v<T>) {
    // Parse as long double first so "300" into uint8 reports the range, not a type error.
    long double v = 0;
    if (!YAML::convert<long double>::decode(n, v)) {
      errors_->add(n.Mark(), key_path(key), "'" + shown + "' is not a number");
      return;
    }
    // NaN compares false with every bound and inf overflows the conversions downstream: no
    // setting here means anything by them, so they are refused for every numeric key.
    if (!std::isfinite(v)) {
      errors_->add(n.Mark(), key_path(key), "'" + shown + "' is not a finite number");
      return;
    }
    // An integer beyond its type (checked exactly: a long double holds every 64-bit integer)
    // is outside the range before it is anything else. The bound was 1.8e19, which refused
    // `sim.seed: 18446744073709551615` (2^64 - 1, what `sim --seed` takes) as "outside [0, inf]".
    if (std::is_integral_v<T> && !in_range(v, std::numeric_limits<T>::lowest(), std::numeric_limits<T>::max())) {
      errors_->add(n.Mark(), key_path(key), shown + " is outside the allowed range " + describe_bounds(lo, hi));
      return;
    }
    if (std::is_integral_v<T> && v != std::floor(v)) {
      errors_->add(n.Mark(), key_path(key), shown + " is not a whole number");
      return;
    }
    if (!in_range(v, lo, hi)) {
      errors_->add(n.Mark(), key_path(key), shown + " is outside the allowed range " + describe_bounds(lo, hi));
      return;
    }
    out = static_cast<T>(v);
  } else {
    T v = n.as<T>();
    if constexpr (std::is_same_v<T, std::string>) {
      if (const std::string why = control_character_problem(v); !why.empty()) {
        errors_->add(n.Mark(), key_path(key), why);
        return;
      }
    }
    out = std::move(v);
  }
}

template <typename T>
void Section::opt(const char* key, T& out, T lo, T hi) {
  read_.insert(key);
  note<T>(key);
  if (!present()) return;
  const YAML::Node n = node_[key];
  if (!n.IsDefined()) return;
  read_scalar(key, n, out, lo, hi);
}

template <typename T>
void Section::req(const char* key, T& out, T lo, T hi) {
  read_.insert(key);
  note<T>(key);
  if (!present() || !node_[key].IsDefined()) {
    errors_->add(node_.Mark(), key_path(key), "required key is missing");
    return;
  }
  read_scalar(key, node_[key], out, lo, hi);
}

template <typename T>
void Section::opt_list(const char* key, std::vector<T>& out, T lo, T hi) {
  read_.insert(key);
  note<T>((std::string(key) + "[0]").c_str());
  if (!present()) return;
  const YAML::Node n = node_[key];
  if (!n.IsDefined()) return;
  if (!n.IsSequence()) {
    errors_->add(n.Mark(), key_path(key), "expected a list, e.g. [1, 2]");
    return;
  }
  std::vector<T> values;
  for (std::size_t i = 0; i < n.size(); ++i) {
    T v{};
    const std::string item = std::string(key) + "[" + std::to_string(i) + "]";
    read_scalar(item.c_str(), n[i], v, lo, hi);
    values.push_back(v);
  }
  out = std::move(values);
}

}  // namespace sempose::config
