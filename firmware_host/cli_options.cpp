// The commands' option parser (cli_options.hpp).
#include "cli_options.hpp"

#include "cli_stdout.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

namespace sempose::cli {

namespace {

const OptionSpec* find_spec(const std::vector<OptionSpec>& spec, std::string_view name) {
  for (const auto& s : spec) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

bool is_help(std::string_view a) { return a == "--help" || a == "-h"; }

// A range bound as a person writes it: 315576000, not 3.15576e+08.
std::string bound(double v) {
  char buf[64];
  if (std::fabs(v) < 1e15 && v == std::floor(v)) std::snprintf(buf, sizeof buf, "%.0f", v);
  else std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string range_text(const OptionSpec& s) {
  const std::string unit = s.unit.empty() ? "" : " of " + std::string(s.unit);
  if (s.kind == OptionKind::kWhole) {
    return "a whole number" + unit + " in [" + std::to_string(s.min_whole) + ", " + std::to_string(s.max_whole) + "]";
  }
  return "a finite number" + unit + " in [" + bound(s.min_real) + ", " + bound(s.max_real) + "]";
}

}  // namespace

bool parse_whole(std::string_view s, unsigned long long& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty() || s.size() > 30) return false;
  for (const char c : s) {
    if (c < '0' || c > '9') return false;
  }
  const std::string copy(s);
  errno = 0;
  char* end = nullptr;
  v = std::strtoull(copy.c_str(), &end, 10);
  return errno == 0 && end == copy.c_str() + copy.size();
}

bool parse_real(std::string_view s, double& v) {
  // [+-] digits [. digits] [(e|E) [+-] digits], at least one digit before the exponent.
  std::size_t i = 0;
  const auto digits = [&] {
    const std::size_t from = i;
    while (i < s.size() && s[i] >= '0' && s[i] <= '9') ++i;
    return i - from;
  };
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
  std::size_t mantissa = digits();
  if (i < s.size() && s[i] == '.') {
    ++i;
    mantissa += digits();
  }
  if (mantissa == 0) return false;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  if (i != s.size() || s.size() > 64) return false;
  const std::string copy(s);
  v = std::strtod(copy.c_str(), nullptr);  // the grammar above is a subset of strtod's
  return std::isfinite(v);                 // 1e999 overflows to inf
}

const OptionValue* ParsedOptions::find(std::string_view name) const {
  if (find_spec(spec_, name) == nullptr) {
    throw std::logic_error("option " + std::string(name) + " is not declared by this command");
  }
  for (const auto& g : given) {
    if (g.name == name) return &g;
  }
  return nullptr;
}

bool ParsedOptions::has(std::string_view name) const { return find(name) != nullptr; }

std::string ParsedOptions::text(std::string_view name, const std::string& fallback) const {
  const OptionValue* v = find(name);
  return v ? v->text : fallback;
}

unsigned long long ParsedOptions::whole(std::string_view name, unsigned long long fallback) const {
  const OptionValue* v = find(name);
  return v ? v->whole : fallback;
}

double ParsedOptions::real(std::string_view name, double fallback) const {
  const OptionValue* v = find(name);
  return v ? v->real : fallback;
}

std::vector<std::string> ParsedOptions::all(std::string_view name) const {
  find(name);
  std::vector<std::string> out;
  for (const auto& g : given) {
    if (g.name == name) out.push_back(g.text);
  }
  return out;
}

ParsedOptions parse_options(const std::vector<OptionSpec>& spec, int argc, char** argv) {
  ParsedOptions p;
  p.spec_ = spec;
  bool help = false;
  auto fail = [&](std::string message, bool usage) {
    if (p.outcome == ParsedOptions::Outcome::kError) return;  // the first problem is the one named
    p.outcome = ParsedOptions::Outcome::kError;
    p.error = std::move(message);
    p.show_usage = usage;
  };
  const OptionSpec* previous = nullptr;  // the option before this word (a flag given a value?)
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (is_help(a)) {
      help = true;
      previous = nullptr;
      continue;
    }
    const OptionSpec* s = find_spec(spec, a);
    if (s == nullptr) {
      const auto eq = a.find('=');
      if (a.substr(0, 2) == "--" && eq != std::string_view::npos && find_spec(spec, a.substr(0, eq)) != nullptr) {
        fail("unknown option '" + std::string(a) + "' (give the value after a space: " + std::string(a.substr(0, eq)) +
                 " " + std::string(a.substr(eq + 1)) + ")",
             true);
      } else if (a.substr(0, 1) == "-") {
        fail("unknown option '" + std::string(a) + "'", true);
      } else if (previous != nullptr && previous->kind == OptionKind::kFlag) {
        fail("unexpected argument '" + std::string(a) + "': " + std::string(previous->name) + " takes no value", true);
      } else {
        fail("unexpected argument '" + std::string(a) + "' (every value follows its option)", true);
      }
      previous = nullptr;
      continue;
    }
    previous = s;
    if (!s->repeatable) {
      for (const auto& g : p.given) {
        if (g.name == s->name) fail("option " + std::string(a) + " is given twice; give it once", false);
      }
    }
    OptionValue v;
    v.name = s->name;
    if (s->kind != OptionKind::kFlag) {
      // The value is the next word, unless there is none or it is one of this command's own
      // options (or --help): then the value was left out.
      if (i + 1 >= argc) {
        fail(std::string(a) + " needs a value", true);
        continue;
      }
      const std::string_view next = argv[i + 1];
      if (find_spec(spec, next) != nullptr || is_help(next)) {
        fail(std::string(a) + " needs a value (the next word is the option " + std::string(next) + ")", true);
        continue;
      }
      v.text = argv[++i];
      if (v.text.empty()) {
        fail(std::string(a) + ": the value is empty" +
                 (s->kind == OptionKind::kText ? "" : "; it must be " + range_text(*s)),
             false);
        continue;
      }
      if (s->kind == OptionKind::kWhole) {
        if (!parse_whole(v.text, v.whole) || v.whole < s->min_whole || v.whole > s->max_whole) {
          fail(std::string(a) + ": '" + v.text + "' is not " + range_text(*s), false);
          continue;
        }
      } else if (s->kind == OptionKind::kReal) {
        // -0 compares equal to 0 but was written negative: `run --duration -0` ran until a signal
        // where -1 is refused (found probing).
        if (!parse_real(v.text, v.real) || !(v.real >= s->min_real && v.real <= s->max_real) ||
            (std::signbit(v.real) && s->min_real >= 0)) {
          fail(std::string(a) + ": '" + v.text + "' is not " + range_text(*s), false);
          continue;
        }
      }
    }
    p.given.push_back(std::move(v));
  }
  if (help) {
    p.outcome = ParsedOptions::Outcome::kHelp;
    p.error.clear();
    return p;
  }
  if (p.outcome == ParsedOptions::Outcome::kError) return p;
  std::string missing;
  int n_missing = 0;
  for (const auto& s : spec) {
    if (!s.required) continue;
    bool given = false;
    for (const auto& g : p.given) given = given || g.name == s.name;
    if (given) continue;
    missing += (missing.empty() ? "" : ", ") + std::string(s.name);
    ++n_missing;
  }
  if (n_missing > 0) fail(missing + (n_missing == 1 ? " is required" : " are required"), true);
  return p;
}

int finish_parse(const char* command, const ParsedOptions& p, int (*usage)(std::FILE*)) {
  switch (p.outcome) {
    case ParsedOptions::Outcome::kOk:
      return -1;
    case ParsedOptions::Outcome::kHelp:
      // The help asked for and lost (stdout full or closed) is no success: exit 4, as the
      // top-level --help (each command's --help said exit 0; hostile round 10).
      usage(stdout);
      return report_lost(command) ? 4 : 0;
    case ParsedOptions::Outcome::kError:
      break;
  }
  std::fprintf(stderr, "sempose %s: %s\n", command, p.error.c_str());
  if (p.show_usage) usage(stderr);
  return 2;
}

}  // namespace sempose::cli
