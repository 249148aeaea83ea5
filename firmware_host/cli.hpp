// The `sempose` subcommands. Each returns the process exit code; argv[0] is the subcommand.
#pragma once

#include <algorithm>
#include <cstdio>
#include <initializer_list>
#include <string>
#include <string_view>

namespace sempose::config {
struct AppConfig;
}

namespace sempose::cli {

int run(int argc, char** argv);      // the controller: pipeline on a scan source (cli_run.cpp)
int sim(int argc, char** argv);      // record a simulated sequence (cli_sim.cpp)
int pattern(int argc, char** argv);  // average frames into a pattern PGM (cli_pattern.cpp)
int replay(int argc, char** argv);   // track through a recorded sequence (cli_replay.cpp)
int check_rt(int argc, char** argv); // RT preflight of this box for a config (cli_check_rt.cpp)
int view(int argc, char** argv);     // operator's pictures of a run or recording (cli_view.cpp)

// The check-rt lines for `cfg` on the system under `root`; returns check-rt's exit code
// (`sempose run --strict-rt` refuses to start on 3).
int print_rt_checks(const config::AppConfig& cfg, const std::string& root);

// "-" names standard output to most tools; where an output is a folder or a binary file whose
// command also reports on stdout, sempose refuses it instead of creating a file called "-".
inline bool refuse_stdout_output(const char* command, const std::string& value, const char* what) {
  if (value != "-") return false;
  std::fprintf(stderr, "sempose %s: --out '-' (standard output) is not supported: --out names %s\n", command, what);
  return true;
}

// An option given twice (`--frames 3 ... --frames 4`) is ambiguous: the later one used to win
// silently, so an operator's edited command line could run with a value they meant to replace
// or keep. Every option but the listed repeatable ones (replay's and view's --pattern, --mask)
// is refused by name when it appears again, before anything is read or written.
inline bool refuse_repeated_options(const char* command, int argc, char** argv,
                                    std::initializer_list<std::string_view> repeatable = {}) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a.size() < 3 || a.substr(0, 2) != "--") continue;
    if (std::find(repeatable.begin(), repeatable.end(), a) != repeatable.end()) continue;
    for (int j = 1; j < i; ++j) {
      if (a == argv[j]) {
        std::fprintf(stderr, "sempose %s: option %s is given twice; give it once\n", command, argv[i]);
        return true;
      }
    }
  }
  return false;
}

}  // namespace sempose::cli
