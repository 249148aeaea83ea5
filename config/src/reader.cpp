#include "sempose/config/reader.hpp"
#include "sempose/config/unsafe_text.hpp"

#include <sys/stat.h>
#include <sys/vfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <cstdio>
#include <limits>
#include <sstream>
#include <vector>

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/parser.h>

namespace sempose::config {

namespace {
// One message line at most ~kMaxMessage bytes: a 10 MB value came back as a 10 MB error line
// (found probing). The cut is in the middle, at UTF-8 characters' starts: the start names file,
// line and key, the end says what is wrong (a 1.4 kB path, legal, lost its "missing?" when the
// end was cut; hostile round 12), and the cut says how much was left out.
std::size_t char_start(const std::string& m, std::size_t i) {
  while (i > 0 && (static_cast<unsigned char>(m[i]) & 0xC0) == 0x80) --i;
  return i;
}

std::string bounded(const std::string& m) {
  constexpr std::size_t kMaxMessage = 1024, kHead = 600, kTail = 300;
  if (m.size() <= kMaxMessage) return m;
  const std::size_t head = char_start(m, kHead), tail = char_start(m, m.size() - kTail);
  return m.substr(0, head) + " ... (" + std::to_string(tail - head) + " bytes left out) ... " + m.substr(tail);
}
}  // namespace

// Every line printable (control, escape, bidirectional and invisible characters, bytes that are
// not UTF-8 written as escapes): a key's name, a refused value and yaml-cpp's syntax messages
// quote the file's own text, and a config holding a terminal escape or a newline in a key put
// raw escapes and a forged line ("summary: poses=999 ok: unknown key") on stderr (found probing).
void Errors::add(const YAML::Mark& mark, const std::string& key, const std::string& what) {
  std::string where = file_;
  if (!mark.is_null()) where += ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
  messages_.push_back(bounded(printable(where + ": " + key + ": " + what)));
  refused_.push_back(key);
}

void Errors::add(const std::string& what) { messages_.push_back(bounded(printable(file_ + ": " + what))); }

std::string Errors::joined() const {
  // Bounded: a file of 100k misspelt keys gave 81 MB of errors (found probing); the first ones
  // name the problem, the count says how big it is.
  constexpr std::size_t kShown = 50;
  std::string out;
  for (std::size_t i = 0; i < messages_.size() && i < kShown; ++i) out += messages_[i] + "\n";
  if (messages_.size() > kShown) {
    out += file_ + ": ... and " + std::to_string(messages_.size() - kShown) + " more errors (the first " +
           std::to_string(kShown) + " shown)\n";
  }
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

std::string number_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

bool tag_is_plain(const std::string& tag) {
  return tag.empty() || tag == "?" || tag == "!" || tag == "tag:yaml.org,2002:str" || tag == "tag:yaml.org,2002:int" ||
         tag == "tag:yaml.org,2002:float" || tag == "tag:yaml.org,2002:bool";
}

std::string tag_kind_problem(const std::string& tag, KeyKind kind) {
  const bool is_bool = tag == "tag:yaml.org,2002:bool", is_number = tag == "tag:yaml.org,2002:int" || tag == "tag:yaml.org,2002:float";
  const bool is_text = tag == "tag:yaml.org,2002:str";
  if (kind == KeyKind::kBool && (is_number || is_text)) return is_text ? "text (!!str)" : "a number (!!" + tag.substr(18) + ")";
  if ((kind == KeyKind::kFloat || kind == KeyKind::kInteger) && (is_bool || is_text))
    return is_text ? "text (!!str)" : "a boolean (!!bool)";
  return "";
}

Section::Section(YAML::Node node, std::string path, Errors& errors)
    : node_(std::move(node)), path_(std::move(path)), errors_(&errors) {
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) {
    errors_->add(node_.Mark(), path_.empty() ? "(top level)" : path_,
                 "expected a mapping of keys (key: value)");
    node_ = YAML::Node();
    not_a_mapping_ = true;
  }
}

Section::Section(Section&& o) noexcept
    : node_(std::move(o.node_)), not_a_mapping_(o.not_a_mapping_), path_(std::move(o.path_)), errors_(o.errors_),
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

void Section::error_at(const std::string& dotted_key, const std::string& what) {
  // Walks "a.b[2].c" from this node; stops at the first part the file does not have.
  YAML::Mark mark = node_.Mark();
  // Lookups go through a const reference: a missing key must not be inserted. reset() moves
  // `at` to the next node without touching node_.
  YAML::Node at = node_;
  std::size_t i = 0;
  while (i < dotted_key.size() && at.IsDefined() && !at.IsNull()) {
    std::size_t end = dotted_key.find_first_of(".[", i);
    if (end == std::string::npos) end = dotted_key.size();
    const std::string name = dotted_key.substr(i, end - i);
    if (!name.empty()) {
      if (!at.IsMap()) break;
      const YAML::Node next = static_cast<const YAML::Node&>(at)[name];
      if (!next.IsDefined()) break;
      at.reset(next);
      mark = at.Mark();
    }
    i = end;
    while (i < dotted_key.size() && dotted_key[i] == '[') {
      const std::size_t close = dotted_key.find(']', i);
      if (close == std::string::npos || !at.IsSequence()) {
        i = dotted_key.size();
        break;
      }
      const std::size_t index = std::strtoul(dotted_key.c_str() + i + 1, nullptr, 10);
      if (index >= at.size()) {
        i = dotted_key.size();
        break;
      }
      const YAML::Node next = static_cast<const YAML::Node&>(at)[index];
      at.reset(next);
      mark = at.Mark();
      i = close + 1;
    }
    if (i < dotted_key.size() && dotted_key[i] == '.') ++i;
  }
  errors_->add(mark, key_path(dotted_key.c_str()), what);
}

void Section::finish() {
  if (finished_) return;
  finished_ = true;
  if (!present()) return;
  // yaml-cpp keeps duplicate keys and lookups return the first: a second value would be
  // silently ignored, so a repeated key is an error naming both lines.
  std::map<std::string, YAML::Mark> seen;
  bool unknown_seen = false;
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar()) {
      errors_->add(kv.first.Mark(), path_.empty() ? "(top level)" : path_,
                   "a key must be a plain name, not a list or mapping");
      continue;
    }
    const std::string k = kv.first.Scalar();
    const auto [it, fresh] = seen.emplace(k, kv.first.Mark());
    if (!fresh) {
      errors_->add(kv.first.Mark(), key_path(k),
                   "duplicate key (first given on line " + std::to_string(it->second.line + 1) + ")");
      continue;
    }
    if (read_.count(k) == 0) {
      // The keys known here listed once per section (with every unknown key it was 1 kB a line).
      std::string known;
      for (const auto& r : read_) known += (known.empty() ? "" : ", ") + r;
      errors_->add(kv.first.Mark(), key_path(k),
                   unknown_seen ? std::string("unknown key (the known ones are listed above)")
                                : "unknown key (known here: " + (known.empty() ? std::string("none") : known) + ")");
      unknown_seen = true;
    }
  }
}

std::string path_kind_problem(const std::string& path) {
  struct stat st {};
  if (path.empty()) return "an empty path";
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) {
      const auto slash = path.rfind('/');
      struct stat dir {};
      if (slash != std::string::npos && slash > 0 && ::stat(path.substr(0, slash).c_str(), &dir) != 0) {
        return "in a missing folder";
      }
      return "missing";
    }
    return std::string("not accessible (") + std::strerror(errno) + ")";
  }
  if (S_ISREG(st.st_mode)) return "";
  if (S_ISDIR(st.st_mode)) return "a directory, not a file";
  if (S_ISFIFO(st.st_mode)) return "a FIFO, not a regular file";
  if (S_ISCHR(st.st_mode)) return "a character device, not a regular file";
  if (S_ISBLK(st.st_mode)) return "a block device, not a regular file";
  if (S_ISSOCK(st.st_mode)) return "a socket, not a regular file";
  return "not a regular file";
}

namespace {
// The kernel's pseudo-filesystems take no new files and no arbitrary writes, whatever access()
// says (root passes it on /proc and /sys): found probing, `view --out /proc/x` failed after
// reading every input with a bare filesystem error and `--hist-dir /sys/kernel` only at exit.
std::string pseudo_filesystem_problem(const std::string& dir) {
  struct statfs fs {};
  if (::statfs(dir.empty() ? "." : dir.c_str(), &fs) != 0) return "";
  switch (static_cast<unsigned long>(fs.f_type)) {
    case 0x9fa0UL:      // PROC_SUPER_MAGIC
      return "on the kernel's /proc filesystem, which takes no files";
    case 0x62656572UL:  // SYSFS_MAGIC
      return "on the kernel's /sys filesystem, which takes no files";
    case 0x64626720UL:  // DEBUGFS_MAGIC
    case 0x74726163UL:  // TRACEFS_MAGIC
    case 0x27e0ebUL:    // CGROUP_SUPER_MAGIC
    case 0x63677270UL:  // CGROUP2_SUPER_MAGIC
      return "on a kernel pseudo-filesystem, which takes no files";
    default:
      return "";
  }
}
}  // namespace

std::string output_path_problem(const std::string& path) {
  if (path.empty()) return "an empty path";
  // "x.csv/" passed while no file of that name existed and failed at open, after the work
  // (found probing: pattern --out p.pgm/ exit 1 once the frames were averaged).
  if (path.back() == '/') return "a folder's name, ending in '/': name the file";
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISREG(st.st_mode) || S_ISCHR(st.st_mode)) {
      return ::access(path.c_str(), W_OK) == 0 ? "" : "not writable";
    }
    return path_kind_problem(path);  // directory, FIFO (would block in open), socket, ...
  }
  if (errno != ENOENT) return std::string("not accessible (") + std::strerror(errno) + ")";
  // A missing file: its folder must exist (or be creatable: sempose makes missing folders).
  std::string dir = path.substr(0, path.rfind('/') == std::string::npos ? 0 : path.rfind('/'));
  while (!dir.empty()) {
    struct stat d {};
    if (::stat(dir.c_str(), &d) == 0) {
      if (!S_ISDIR(d.st_mode)) return "below '" + dir + "', which is not a directory";
      if (const std::string why = pseudo_filesystem_problem(dir); !why.empty()) return "in folder '" + dir + "', " + why;
      return ::access(dir.c_str(), W_OK | X_OK) == 0 ? "" : "in folder '" + dir + "', which is not writable";
    }
    const auto slash = dir.rfind('/');
    dir = slash == std::string::npos ? std::string() : dir.substr(0, slash);
  }
  return "";
}

std::string output_dir_problem(const std::string& path) {
  if (path.empty()) return "an empty path";
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISREG(st.st_mode)) return "a regular file, not a directory";
    if (!S_ISDIR(st.st_mode)) return path_kind_problem(path);
    if (const std::string why = pseudo_filesystem_problem(path); !why.empty()) return "a directory " + why;
    return ::access(path.c_str(), W_OK | X_OK) == 0 ? "" : "a directory that is not writable";
  }
  // Missing: it is created, so the nearest existing ancestor must be a writable directory.
  return output_path_problem(path + "/x");
}

std::string printable(const std::string& value) {
  std::string out;
  std::size_t i = 0;
  for (UnsafeCharacter u = find_unsafe_character(value); u.found; u = find_unsafe_character(value, i, u.position)) {
    out.append(value, i, u.byte - i);
    out += u.escape;
    i = u.byte + u.length;
  }
  out.append(value, i, std::string::npos);
  return out;
}

std::string terminal_text(const std::string& message) {
  std::string out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = message.find('\n', start);
    out += bounded(printable(message.substr(start, end == std::string::npos ? std::string::npos : end - start)));
    if (end == std::string::npos) return out;
    out += '\n';
    start = end + 1;
  }
}

std::string control_character_problem(const std::string& value) {
  const UnsafeCharacter u = find_unsafe_character(value);
  if (!u.found) return "";
  std::string bytes = u.length == 1 ? "byte" : "bytes";
  for (std::size_t k = 0; k < u.length; ++k) {
    char b[8];
    std::snprintf(b, sizeof b, " 0x%02x", static_cast<unsigned char>(value[u.byte + k]));
    bytes += b;
  }
  return "'" + printable(value) + "' holds " + u.what + ", " + bytes + " at character " + std::to_string(u.position) +
         ": control characters are not allowed (a file name with one breaks every line-oriented tool and log)";
}

namespace {
YAML::Node checked_root(YAML::Node root, Errors& errors) {
  if (!root.IsMap()) {
    errors.add("the top level must be a mapping of sections (sim:, tracker:, ...)");
    return {};
  }
  return root;
}
}  // namespace

namespace {
// Notes whether a YAML document holds anything (a node other than an empty one) and where.
class DocumentContent final : public YAML::EventHandler {
 public:
  bool content = false;
  YAML::Mark mark;
  std::vector<YAML::Mark> quoted;  // where each quoted scalar starts
  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override { note(m); }
  void OnScalar(const YAML::Mark& m, const std::string& tag, YAML::anchor_t, const std::string&) override {
    note(m);
    if (tag == "!") quoted.push_back(m);  // the non-specific tag: a quoted scalar
  }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    note(m);
  }
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    note(m);
  }
  void OnMapEnd() override {}

 private:
  void note(const YAML::Mark& m) {
    if (!content) mark = m;
    content = true;
  }
};
}  // namespace

namespace {
// Whether the quoted scalar opening at text[pos] ('"' or '\'') has its closing quote: yaml-cpp
// takes the end of the file for it, so an unclosed quote swallowed every line after it into one
// value and was reported as that value (`source: 'sim scan: {field_w: 1024} ' is not one of ...`).
bool quote_closed(const std::string& text, std::size_t pos) {
  if (pos >= text.size() || (text[pos] != '"' && text[pos] != '\'')) return true;  // not where we think
  const char q = text[pos];
  for (std::size_t i = pos + 1; i < text.size(); ++i) {
    if (q == '"' && text[i] == '\\') {
      ++i;  // an escaped character, \" among them
    } else if (text[i] == q) {
      if (q == '\'' && i + 1 < text.size() && text[i + 1] == '\'') {
        ++i;  // '' is a quote inside single quotes
      } else {
        return true;
      }
    }
  }
  return false;
}
}  // namespace

YAML::Node load_text(const std::string& text, Errors& errors) {
  // Lines ended by CR alone (an old Mac editor's) read as one line: the error said only that the
  // top level is not a mapping (found probing). CRLF is read as it should be.
  if (text.find('\r') != std::string::npos && text.find('\n') == std::string::npos) {
    errors.add("its lines end in a carriage return alone (CR, old Mac line endings), so YAML reads one line: "
               "convert them to LF (e.g. tr '\\r' '\\n')");
    return {};
  }
  // A NUL byte is no text (a binary file, or a file cut by a crash): YAML stopped at it and called
  // it "unknown escape character", the message cut there too (found probing).
  if (const std::size_t nul = text.find('\0'); nul != std::string::npos) {
    YAML::Mark at;
    at.pos = static_cast<int>(nul);
    at.line = static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(nul), '\n'));
    const std::size_t line_start = nul == 0 ? std::string::npos : text.rfind('\n', nul - 1);
    at.column = static_cast<int>(line_start == std::string::npos ? nul : nul - line_start - 1);
    errors.add(at, "(text)", "a NUL byte: a config is text (is this a binary file, or one cut by a crash?)");
    return {};
  }
  try {
    YAML::Node root = YAML::Load(text);
    // One config per file: YAML::Load reads the first document of a multi-document stream and
    // drops the rest without a word (a `---` and a second set of sections, e.g. two configs
    // concatenated, ran the first one). A second document that holds anything is an error.
    // Two documents are parsed at most: YAML::LoadAll looped without end on some malformed
    // streams (fuzz_config: a 584-byte input, 1.3 GB of empty documents before its timeout).
    std::istringstream in(text);
    YAML::Parser parser(in);
    DocumentContent first, second;
    const bool read_first = parser.HandleNextDocument(first);
    for (const YAML::Mark& m : first.quoted) {
      if (m.pos >= 0 && !quote_closed(text, static_cast<std::size_t>(m.pos))) {
        errors.add(m, "(syntax)", "a quote opened here is never closed (the value ran to the end of the file)");
        return {};
      }
    }
    if (read_first && parser.HandleNextDocument(second) && second.content) {
      errors.add(second.mark, "(document 2)", "a second YAML document (after ---); a config file holds one document");
      return {};
    }
    return checked_root(root, errors);
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's own message for this is "bad file": 100,000 `[` or `{` (or as many nested
    // indented levels) said nothing of what is wrong.
    errors.add(e.mark, "(syntax)",
               "lists or mappings nested too deep for the YAML reader (a config is a few levels deep: an unclosed "
               "'[' or '{'?)");
  } catch (const YAML::Exception& e) {
    errors.add(e.mark, "(syntax)", e.msg);
  } catch (const std::exception& e) {
    errors.add(std::string("cannot be read as YAML: ") + e.what());
  }
  return {};
}

YAML::Node load_file(const std::string& path, Errors& errors) {
  const std::string kind = path_kind_problem(path);
  if (!kind.empty()) {
    errors.add("cannot read the config: it is " + kind);
    return {};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    errors.add(std::string("cannot open the config (") + std::strerror(errno) + ")");
    return {};
  }
  std::string text;
  // On the heap: 64 KiB on the stack was a SIGSEGV under `ulimit -s 64` (found probing).
  std::vector<char> buf(65536);
  while (in.read(buf.data(), static_cast<std::streamsize>(buf.size())) || in.gcount() > 0) {
    text.append(buf.data(), static_cast<std::size_t>(in.gcount()));
    if (static_cast<long long>(text.size()) > kMaxConfigBytes) {
      errors.add("the config is larger than " + std::to_string(kMaxConfigBytes >> 20) + " MiB");
      return {};
    }
  }
  if (in.bad()) {
    errors.add("read error");
    return {};
  }
  return load_text(text, errors);
}

}  // namespace sempose::config
