// One option parser for the six `sempose` commands. Each command declares its options (name,
// flag or value, repeatable or not, whole or real number with its allowed range, required or
// not) and parse_options() checks the whole command line against that table before the
// command reads or writes anything:
//   - an option the command does not have (named, with the command's usage), or a word that
//     is not an option at all;
//   - an option without its value (the last word, or followed by another of the command's
//     options: `--out --frames 3` used to make a folder called "--frames");
//   - an empty value (`--config ''` used to mean "no config" for check-rt and replay, and
//     `--hist-dir ''` / `--can-log ''` fell back to the config's without a word);
//   - an option given twice that may not repeat (the later one used to win silently);
//   - a number that is not a plain decimal number (hex, `12abc`, ` 5`), not finite, or
//     outside its range, naming option, value and range;
//   - a required option that is missing.
// `--help` / `-h` anywhere (as an option, not as a value) asks for the usage on stdout.
// Setup code only (allocates); never on the RT path.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

namespace sempose::cli {

enum class OptionKind {
  kFlag,   // no value: `--strict-rt`
  kText,   // any non-empty text: a path, `X,Y`
  kWhole,  // a whole number in [min_whole, max_whole] (decimal digits only)
  kReal,   // a finite decimal number in [min_real, max_real]
};

struct OptionSpec {
  std::string_view name;        // "--frames"
  OptionKind kind = OptionKind::kText;
  bool repeatable = false;      // `--pattern`, `--mask`
  bool required = false;
  unsigned long long min_whole = 0, max_whole = 0;
  double min_real = 0, max_real = 0;
  std::string_view unit = {};   // named with the range in errors: "ns", "seconds"
};

// Shorthands for the tables.
constexpr OptionSpec flag(std::string_view name) { return {name, OptionKind::kFlag}; }
constexpr OptionSpec text(std::string_view name, bool required = false, bool repeatable = false) {
  return {name, OptionKind::kText, repeatable, required};
}
constexpr OptionSpec whole(std::string_view name, unsigned long long lo, unsigned long long hi, std::string_view unit = {}) {
  return {name, OptionKind::kWhole, false, false, lo, hi, 0, 0, unit};
}
constexpr OptionSpec real(std::string_view name, double lo, double hi, std::string_view unit = {}) {
  return {name, OptionKind::kReal, false, false, 0, 0, lo, hi, unit};
}

struct OptionValue {
  std::string_view name;  // the spec's name
  std::string text;       // as given ("" for a flag)
  unsigned long long whole = 0;
  double real = 0;
};

class ParsedOptions {
 public:
  enum class Outcome { kOk, kHelp, kError };
  Outcome outcome = Outcome::kOk;
  std::string error;        // kError: what is wrong, naming option and value
  bool show_usage = false;  // kError: the command's usage belongs after the error

  // Every option given, in command-line order (replay pairs each --mask with its --pattern).
  std::vector<OptionValue> given;

  // Accessors by the spec's name; asking for a name that is not in the spec throws
  // std::logic_error (a typo in a command, found by its tests).
  bool has(std::string_view name) const;
  std::string text(std::string_view name, const std::string& fallback = {}) const;
  unsigned long long whole(std::string_view name, unsigned long long fallback) const;
  double real(std::string_view name, double fallback) const;
  std::vector<std::string> all(std::string_view name) const;  // a repeatable option's values

 private:
  friend ParsedOptions parse_options(const std::vector<OptionSpec>&, int, char**);
  const OptionValue* find(std::string_view name) const;
  std::vector<OptionSpec> spec_;
};

// argv[0] is the command's name (it is skipped).
ParsedOptions parse_options(const std::vector<OptionSpec>& spec, int argc, char** argv);

// Strict number grammar shared with values inside an option (`--center X,Y`): optional '+',
// decimal digits; reals also '-', a fraction and an exponent. No hex, no spaces, no suffix.
bool parse_whole(std::string_view s, unsigned long long& v);
bool parse_real(std::string_view s, double& v);  // false also for a result that is not finite

// For a command: prints the error (and the usage when it belongs) and gives the exit code to
// return, or -1 when the command goes on. `usage(out)` prints the usage to `out` and returns
// 0 for stdout (help asked for), 2 otherwise.
int finish_parse(const char* command, const ParsedOptions& p, int (*usage)(std::FILE*));

}  // namespace sempose::cli
