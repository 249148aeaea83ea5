// The rules of the commands' option parser (firmware_host/cli_options.hpp), on a table like
// the commands' own: every kind of bad command line is refused by name, with the option, the
// value and the allowed range, and a valid one gives its values in command-line order.
#include <gtest/gtest.h>

#include <initializer_list>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cli_options.hpp"

namespace {

using namespace sempose::cli;
using Outcome = ParsedOptions::Outcome;

const std::vector<OptionSpec> kSpec = {
    text("--out", true),
    text("--config"),
    text("--pattern", false, true),
    flag("--strict-rt"),
    whole("--frames", 1, 1'000'000),
    whole("--seed", 0, ~0ULL),
    real("--duration", 0, 315576000, "seconds"),
};

ParsedOptions parse(std::initializer_list<const char*> words) {
  std::vector<std::string> copy = {"cmd"};
  copy.insert(copy.end(), words.begin(), words.end());
  std::vector<char*> argv;
  for (auto& w : copy) argv.push_back(w.data());
  return parse_options(kSpec, static_cast<int>(argv.size()), argv.data());
}

// The error, or a note that there was none.
std::string error_of(const ParsedOptions& p) { return p.outcome == Outcome::kError ? p.error : "(no error)"; }

TEST(CliOptions, AValidCommandLineGivesItsValues) {
  const ParsedOptions p = parse({"--out", "d", "--pattern", "a.pgm", "--frames", "+12", "--strict-rt", "--pattern", "b.pgm",
                                 "--duration", "1e3", "--seed", "18446744073709551615"});
  ASSERT_EQ(p.outcome, Outcome::kOk) << p.error;
  EXPECT_EQ(p.text("--out"), "d");
  EXPECT_EQ(p.text("--config", "none"), "none");
  EXPECT_FALSE(p.has("--config"));
  EXPECT_TRUE(p.has("--strict-rt"));
  EXPECT_EQ(p.whole("--frames", 100), 12u);
  EXPECT_EQ(p.whole("--seed", 0), ~0ULL);
  EXPECT_DOUBLE_EQ(p.real("--duration", 0), 1000.0);
  EXPECT_EQ(p.all("--pattern"), (std::vector<std::string>{"a.pgm", "b.pgm"}));
  ASSERT_EQ(p.given.size(), 7u);
  EXPECT_EQ(p.given[2].name, "--frames");  // command-line order (replay pairs --mask with its --pattern)
  EXPECT_EQ(p.given[4].text, "b.pgm");
}

TEST(CliOptions, DefaultsWhenAnOptionalOptionIsLeftOut) {
  const ParsedOptions p = parse({"--out", "d"});
  ASSERT_EQ(p.outcome, Outcome::kOk) << p.error;
  EXPECT_EQ(p.whole("--frames", 100), 100u);
  EXPECT_DOUBLE_EQ(p.real("--duration", 0), 0.0);
  EXPECT_FALSE(p.has("--strict-rt"));
  EXPECT_TRUE(p.all("--pattern").empty());
}

TEST(CliOptions, AnUnknownOptionIsNamedWithTheUsage) {
  ParsedOptions p = parse({"--out", "d", "--frame", "3"});
  EXPECT_EQ(p.outcome, Outcome::kError);
  EXPECT_EQ(error_of(p), "unknown option '--frame'");
  EXPECT_TRUE(p.show_usage);
  p = parse({"--out", "d", "--frames=3"});
  EXPECT_EQ(error_of(p), "unknown option '--frames=3' (give the value after a space: --frames 3)");
  p = parse({"--out", "d", "stray"});
  EXPECT_EQ(error_of(p), "unexpected argument 'stray' (every value follows its option)");
  EXPECT_TRUE(p.show_usage);
  p = parse({"--out", "d", "--strict-rt", "yes"});
  EXPECT_EQ(error_of(p), "unexpected argument 'yes': --strict-rt takes no value");
  p = parse({"--out", "d", "-x"});
  EXPECT_EQ(error_of(p), "unknown option '-x'");
}

TEST(CliOptions, AMissingValueIsNamed) {
  ParsedOptions p = parse({"--out"});
  EXPECT_EQ(error_of(p), "--out needs a value");
  // The option's path left out and the next option taken as it: `--hist-dir --strict-rt` used to
  // run without --strict-rt, writing histograms into a folder called "--strict-rt".
  p = parse({"--config", "--strict-rt", "--out", "d"});
  EXPECT_EQ(error_of(p), "--config needs a value (the next word is the option --strict-rt)");
  p = parse({"--out", "--frames", "3"});
  EXPECT_EQ(error_of(p), "--out needs a value (the next word is the option --frames)");
  // A word that only looks like an option is a value (a negative number is judged as a number).
  p = parse({"--out", "-", "--config", "--not-an-option"});
  EXPECT_EQ(p.outcome, Outcome::kOk) << p.error;
  EXPECT_EQ(p.text("--config"), "--not-an-option");
}

TEST(CliOptions, AnEmptyValueIsRefused) {
  EXPECT_EQ(error_of(parse({"--out", ""})), "--out: the value is empty");
  EXPECT_EQ(error_of(parse({"--out", "d", "--config", ""})), "--config: the value is empty");
  EXPECT_EQ(error_of(parse({"--out", "d", "--frames", ""})), "--frames: the value is empty; it must be a whole number in [1, 1000000]");
}

TEST(CliOptions, AnOptionGivenTwiceIsRefusedUnlessItRepeats) {
  ParsedOptions p = parse({"--out", "a", "--frames", "3", "--out", "b"});
  EXPECT_EQ(error_of(p), "option --out is given twice; give it once");
  p = parse({"--out", "a", "--strict-rt", "--strict-rt"});
  EXPECT_EQ(error_of(p), "option --strict-rt is given twice; give it once");
  p = parse({"--out", "a", "--pattern", "p", "--pattern", "p"});
  EXPECT_EQ(p.outcome, Outcome::kOk) << p.error;
  EXPECT_EQ(p.all("--pattern").size(), 2u);
}

TEST(CliOptions, WholeNumbersAreDecimalAndInRange) {
  for (const char* bad : {"0", "1000001", "-1", " 5", "5 ", "0x10", "1e3", "12abc", "1.5", "nan", "inf", "+", "++5",
                          "99999999999999999999999", "１"}) {
    const ParsedOptions p = parse({"--out", "d", "--frames", bad});
    EXPECT_EQ(error_of(p), std::string("--frames: '") + bad + "' is not a whole number in [1, 1000000]") << bad;
    EXPECT_FALSE(p.show_usage) << bad;
  }
  for (const char* good : {"1", "1000000", "007", "+5"}) {
    const ParsedOptions p = parse({"--out", "d", "--frames", good});
    EXPECT_EQ(p.outcome, Outcome::kOk) << good << ": " << p.error;
  }
  // 2^64 does not fit: refused, not wrapped.
  EXPECT_EQ(error_of(parse({"--out", "d", "--seed", "18446744073709551616"})),
            "--seed: '18446744073709551616' is not a whole number in [0, 18446744073709551615]");
}

TEST(CliOptions, RealNumbersAreFiniteDecimalAndInRange) {
  for (const char* bad : {"nan", "NaN", "inf", "-inf", "infinity", "1e400", "0x10", "0x1p3", "12abc", ".", "1e", "e5", "-",
                          "-1", "315576001", "1e10", " 1", "1,5", ""}) {
    const ParsedOptions p = parse({"--out", "d", "--duration", bad});
    ASSERT_EQ(p.outcome, Outcome::kError) << bad;
    EXPECT_NE(p.error.find("--duration"), std::string::npos) << p.error;
    EXPECT_NE(p.error.find("a finite number of seconds in [0, 315576000]"), std::string::npos) << p.error;
    if (*bad != '\0') {
      EXPECT_NE(p.error.find(std::string("'") + bad + "'"), std::string::npos) << p.error;
    }
  }
  for (const auto& [word, value] : std::vector<std::pair<const char*, double>>{
           {"0", 0}, {"0.5", 0.5}, {".5", 0.5}, {"5.", 5}, {"+2", 2}, {"1e3", 1000}, {"2E-1", 0.2}, {"315576000", 315576000}}) {
    const ParsedOptions p = parse({"--out", "d", "--duration", word});
    ASSERT_EQ(p.outcome, Outcome::kOk) << word << ": " << p.error;
    EXPECT_DOUBLE_EQ(p.real("--duration", -1), value) << word;
  }
}

TEST(CliOptions, NumberGrammarForValuesInsideAnOption) {
  double v = 0;
  EXPECT_TRUE(parse_real("-12.5", v));
  EXPECT_DOUBLE_EQ(v, -12.5);
  EXPECT_FALSE(parse_real("0x140", v));
  EXPECT_FALSE(parse_real("nan", v));
  EXPECT_FALSE(parse_real("", v));
  unsigned long long w = 0;
  EXPECT_TRUE(parse_whole("42", w));
  EXPECT_EQ(w, 42u);
  EXPECT_FALSE(parse_whole("-42", w));
}

TEST(CliOptions, RequiredOptionsAreNamed) {
  ParsedOptions p = parse({"--frames", "3"});
  EXPECT_EQ(error_of(p), "--out is required");
  EXPECT_TRUE(p.show_usage);
  const std::vector<OptionSpec> two = {text("--frames", true), text("--center", true), text("--out", true)};
  std::vector<std::string> words = {"pattern", "--frames", "f"};
  std::vector<char*> argv;
  for (auto& w : words) argv.push_back(w.data());
  p = parse_options(two, static_cast<int>(argv.size()), argv.data());
  EXPECT_EQ(error_of(p), "--center, --out are required");
}

TEST(CliOptions, HelpAnywhereWins) {
  EXPECT_EQ(parse({"--help"}).outcome, Outcome::kHelp);
  EXPECT_EQ(parse({"--frames", "abc", "-h"}).outcome, Outcome::kHelp);
  EXPECT_EQ(parse({"--out", "d", "--bogus", "--help"}).outcome, Outcome::kHelp);
  // As the value of an option, --help is not taken as a path either.
  EXPECT_EQ(parse({"--out", "--help"}).outcome, Outcome::kHelp);
}

TEST(CliOptions, TheFirstProblemIsTheOneNamed) {
  const ParsedOptions p = parse({"--frames", "0", "--bogus", "--out", "a", "--out", "b"});
  EXPECT_EQ(error_of(p), "--frames: '0' is not a whole number in [1, 1000000]");
}

TEST(CliOptions, AskingForAnUndeclaredOptionIsAProgrammingError) {
  const ParsedOptions p = parse({"--out", "d"});
  EXPECT_THROW((void)p.has("--outt"), std::logic_error);
  EXPECT_THROW((void)p.text("--frame"), std::logic_error);
}

TEST(CliOptions, FinishParseGivesTheExitCodes) {
  static int usage_calls = 0;
  auto usage = [](std::FILE* out) {
    ++usage_calls;
    return out == stdout ? 0 : 2;
  };
  usage_calls = 0;
  EXPECT_EQ(finish_parse("test", parse({"--out", "d"}), usage), -1);
  EXPECT_EQ(usage_calls, 0);
  EXPECT_EQ(finish_parse("test", parse({"--help"}), usage), 0);
  EXPECT_EQ(usage_calls, 1);
  EXPECT_EQ(finish_parse("test", parse({"--bogus"}), usage), 2);
  EXPECT_EQ(usage_calls, 2);  // the usage follows an unknown option
  EXPECT_EQ(finish_parse("test", parse({"--out", "d", "--frames", "0"}), usage), 2);
  EXPECT_EQ(usage_calls, 2);  // a bad value is named without it
}

}  // namespace
