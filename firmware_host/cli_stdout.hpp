// Standard output as a command's report channel: whether it was closed at start, whether the
// report was lost. No dependencies: the option parser uses it for --help too.
#pragma once

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace sempose::cli {

// Whether standard output was closed when the process started (a wrapper's `>&-`): main() puts
// a closed stream on /dev/null so that no file takes its number, and a command whose product is
// standard output itself (`replay --out -`) refuses rather than lose every line (found probing:
// exit 0, the poses gone). Set once by main() before any command runs.
inline bool& stdout_started_closed() {
  static bool closed = false;
  return closed;
}

// At a command's end: whether its report on standard output was lost (stdout on a full disk,
// /dev/full, a closed pipe), said on stderr. Found probing: replay's truth and summary lines,
// pattern's and view's lines were lost with nothing on stderr and exit 0.
// Standard output closed when sempose started (`>&-`, put on /dev/null by main) loses the report
// as surely as a full disk: said and exit 4, as coreutils treat a closed stdout (it was exit 0
// with nothing said; hostile round 10).
inline bool report_lost(const char* command) {
  if (stdout_started_closed()) {
    std::fflush(stdout);
    std::fprintf(stderr, "sempose %s: standard output was closed when sempose started: the report was not written\n", command);
    return true;
  }
  if (std::fflush(stdout) == 0 && !std::ferror(stdout)) return false;
  std::fprintf(stderr, "sempose %s: standard output: the report could not be written (%s)\n", command, std::strerror(errno));
  return true;
}

}  // namespace sempose::cli
