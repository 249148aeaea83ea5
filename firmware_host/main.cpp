// sempose: hard-real-time vision controller for robotic nanohandling in an SEM.
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>

#include "cli.hpp"
#include "sempose/config/reader.hpp"

namespace {

struct Command {
  const char* name;
  int (*fn)(int, char**);
  const char* help;
};

constexpr Command kCommands[] = {
    {"run", sempose::cli::run, "run the controller (pipeline, governor, CAN output)"},
    {"sim", sempose::cli::sim, "record a simulated SEM sequence with ground truth"},
    {"pattern", sempose::cli::pattern, "make a pattern PGM from recorded frames"},
    {"replay", sempose::cli::replay, "track through a recorded sequence"},
    {"check-rt", sempose::cli::check_rt, "check this box's real-time settings for a config (pass/warn/fail + fix)"},
    {"view", sempose::cli::view, "operator's view: ROI pictures with the pattern at the pose, pose plot"},
};

int usage(std::FILE* out) {
  std::fprintf(out, "usage: sempose <command> [options]   (sempose <command> --help; sempose --version)\n\ncommands:\n");
  for (const auto& c : kCommands) std::fprintf(out, "  %-9s %s\n", c.name, c.help);
  // The help asked for and lost (stdout on a full disk, or closed) is no success (found probing: exit 0).
  if (out == stdout) return sempose::cli::report_lost("--help") ? 4 : 0;
  return 2;
}

// A standard stream started closed (a wrapper's `>&-`, a supervisor that closes them) left its
// number free, the first file opened took it, and the status lines and warnings went into the
// candump log or the poses CSV (found probing: run with stdout closed, 10 status lines among the
// candump lines; replay's CSV began with its report). Each closed one is put on /dev/null: what
// would have been written there is dropped, as the caller asked by closing it.
void keep_standard_streams_open() {
  for (int fd = 0; fd <= 2; ++fd) {
    if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
    if (fd == 1) sempose::cli::stdout_started_closed() = true;
    // open() takes the lowest free number: fd itself, since every number below it is open by now.
    ::open("/dev/null", fd == 0 ? O_RDONLY : O_WRONLY);
  }
}
}  // namespace

int main(int argc, char** argv) {
  keep_standard_streams_open();
  // A file-size limit (`ulimit -f`, RLIMIT_FSIZE) reached by an output: the default action of
  // SIGXFSZ killed the process mid-line (run: a cut CSV line, no summary, exit 153). Ignored,
  // the write fails with EFBIG and is reported like a full disk (run: exit 4, counted).
  ::signal(SIGXFSZ, SIG_IGN);
  if (argc < 2) return usage(stderr);
  if (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) return usage(stdout);
  // Which build a lab runs (a bug report, the package against the binary): the package's version.
  if (std::strcmp(argv[1], "--version") == 0) {
    // A stray word after it was ignored (found probing): refused, as every command refuses one.
    if (argc > 2) {
      std::fprintf(stderr, "sempose: unexpected argument '%s' after --version\n", argv[2]);
      return 2;
    }
    std::printf("sempose %s\n", SEMPOSE_VERSION);
    return sempose::cli::report_lost("--version") ? 4 : 0;
  }
  for (const auto& c : kCommands) {
    if (std::strcmp(argv[1], c.name) != 0) continue;
    // Every command handles its own expected errors; anything that still escapes (a library
    // throwing where nobody expected it) becomes a named error and exit 2, never an abort.
    try {
      return c.fn(argc - 1, argv + 1);
    } catch (const std::bad_alloc&) {
      // Not only during setup: under `ulimit -v` a run could go its whole length and fail at the
      // end (found probing), where "during setup" misled.
      std::fprintf(stderr, "sempose %s: error: out of memory (the machine's, or an address-space limit: ulimit -v, "
                   "RLIMIT_AS)\n", c.name);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "sempose %s: error: %s\n", c.name, sempose::config::terminal_text(e.what()).c_str());
    } catch (...) {
      std::fprintf(stderr, "sempose %s: error: unexpected failure (unknown exception)\n", c.name);
    }
    return 2;
  }
  std::fprintf(stderr, "sempose: unknown command '%s'\n", argv[1]);
  return usage(stderr);
}
