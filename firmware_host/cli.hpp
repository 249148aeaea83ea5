// The `sempose` subcommands. Each returns the process exit code; argv[0] is the subcommand.
#pragma once

#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <new>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "cli_stdout.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/hal/replay_source.hpp"

namespace sempose::config {
struct AppConfig;
std::string control_character_problem(const std::string& value);  // config/reader.hpp
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

// What an exception says, for an error line: its text escaped (config::terminal_text), and
// memory running out named as such (sim, pattern and view printed a bare "std::bad_alloc"
// under `ulimit -v`; hostile round 10).
inline std::string error_text(const std::exception& e) {
  if (dynamic_cast<const std::bad_alloc*>(&e) != nullptr)
    return "out of memory (the machine's, or an address-space limit: ulimit -v, RLIMIT_AS)";
  return config::terminal_text(e.what());
}

// Whether an output path is this process's standard output or error itself (/dev/stdout,
// /proc/self/fd/2, the terminal or file they are open on): "standard output" / "standard error",
// else nullptr. Found probing: `output.poses_csv: /dev/stdout` opened the file stdout was
// redirected to a second time, and the CSV and the status lines wrote over each other (the
// header gone, lines torn, exit 0). The null device is no stream to mix: it is never one.
inline bool is_null_device(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISCHR(st.st_mode) && st.st_rdev == makedev(1, 3);
}
inline const char* standard_stream_named(const std::string& path) {
  if (path.empty() || path == "-" || is_null_device(path)) return nullptr;
  struct stat out {};
  if (::stat(path.c_str(), &out) != 0) return nullptr;
  for (const auto& [fd, name] : {std::pair{1, "standard output"}, std::pair{2, "standard error"}}) {
    struct stat s {};
    if (::fstat(fd, &s) == 0 && s.st_dev == out.st_dev && s.st_ino == out.st_ino) return name;
  }
  return nullptr;
}

// "-" names standard output to most tools; where an output is a folder or a binary file whose
// command also reports on stdout, sempose refuses it instead of creating a file called "-" — and
// refuses a path that is the standard output or error stream itself (standard_stream_named).
inline bool refuse_stdout_output(const char* command, const std::string& value, const char* what) {
  if (const char* stream = standard_stream_named(value)) {
    std::fprintf(stderr, "sempose %s: --out '%s' is this process's %s, which carries its report: --out names %s\n", command,
                 value.c_str(), stream, what);
    return true;
  }
  if (value != "-") return false;
  std::fprintf(stderr, "sempose %s: --out '-' (standard output) is not supported: --out names %s\n", command, what);
  return true;
}

// An output path with a control character (a newline, a tab, an escape): refused, naming the
// option and the character, before any output is touched. Found probing: `--out $'a\nb.csv'`
// was used as it stood, and a file name with a newline breaks every line-oriented tool and log.
inline bool refuse_control_characters(const char* command, const char* option, const std::string& value) {
  const std::string why = config::control_character_problem(value);
  if (why.empty()) return false;
  std::fprintf(stderr, "sempose %s: %s: %s\n", command, option, why.c_str());
  return true;
}

// An output that names one of the command's own inputs destroys it (found probing: `replay
// --out P.pgm` wrote its CSV over its own pattern, `--out REC/frames.csv` over the recording's
// time stamps, `run --can-log CONFIG` the CAN log over the config; each exited 0). `inputs` are
// (what, path) pairs; the files of a recording are added with add_recording(). Returns a
// message naming the output and the input, or "" when the output is none of them.
struct NamedPath {
  std::string what;  // "--pattern", "targets[0].pattern_sets[0].file", "frame of --frames"
  std::string path;
};

inline void add_recording(std::vector<NamedPath>& inputs, const std::string& what, const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  inputs.push_back({"the time stamps of " + what, dir + "/frames.csv"});
  // The truth `sempose sim` records beside the frames: the next `replay --truth` reads it.
  inputs.push_back({"the ground truth of " + what, dir + "/ground_truth.csv"});
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (hal::is_pgm_name(it->path().string())) inputs.push_back({"a frame of " + what, it->path().string()});
  }
}

// Where writing `path` lands: its symbolic links followed, also one whose target does not exist
// yet (writing through it creates the target), then made absolute and normal. Found probing:
// `pattern --out LINK` with LINK → a frame of the recording passed the "not in the frames
// folder" check, which looked at LINK's own folder, and overwrote the frame.
inline std::filesystem::path resolved_output(const std::string& path) {
  std::error_code ec;
  std::filesystem::path p = std::filesystem::absolute(path, ec);
  if (ec) return path;
  for (int hops = 0; hops < 40 && std::filesystem::is_symlink(std::filesystem::symlink_status(p, ec)); ++hops) {
    const std::filesystem::path target = std::filesystem::read_symlink(p, ec);
    if (ec) break;
    p = target.is_absolute() ? target : p.parent_path() / target;
  }
  const std::filesystem::path canonical = std::filesystem::weakly_canonical(p, ec);
  return ec ? p.lexically_normal() : canonical;
}

// Whether two output paths land on one file: the same file (hard links too) or the same place.
// The null device takes both without mixing anything (a run that keeps neither).
inline bool same_output(const std::string& a, const std::string& b) {
  if (a.empty() || b.empty() || a == "-" || b == "-" || is_null_device(a)) return false;
  std::error_code ec;
  if (std::filesystem::equivalent(a, b, ec) && !ec) return true;
  return resolved_output(a) == resolved_output(b);
}

// Whether writing `out` puts a file into folder `dir` (through links too).
inline bool output_in_folder(const std::string& out, const std::string& dir) {
  if (out.empty() || out == "-" || dir.empty()) return false;
  std::error_code ec;
  const bool in = std::filesystem::equivalent(resolved_output(out).parent_path(), dir, ec);
  return in && !ec;
}

inline std::string output_overwrites_input(const std::string& what, const std::string& out,
                                           const std::vector<NamedPath>& inputs) {
  if (out.empty() || out == "-") return "";
  for (const auto& in : inputs) {
    std::error_code ec;
    if (!in.path.empty() && std::filesystem::equivalent(out, in.path, ec) && !ec) {
      return what + " '" + out + "' is " + in.what + " ('" + in.path + "'): writing it would destroy that input";
    }
  }
  return "";
}

// Standard output or error redirected onto one of the command's inputs (found probing: `replay
// --out - >> REC/frames.csv` and `run >> CONFIG` exited 0 with the recording's time stamps or
// the config replaced or grown by what they wrote). A message naming the stream and the input,
// or "" when neither stream is a file among the inputs.
inline std::string stream_overwrites_input(const std::vector<NamedPath>& inputs) {
  for (const auto& [fd, name] : {std::pair{1, "standard output"}, std::pair{2, "standard error"}}) {
    struct stat s {};
    if (::fstat(fd, &s) != 0 || !S_ISREG(s.st_mode)) continue;
    for (const auto& in : inputs) {
      struct stat t {};
      if (!in.path.empty() && ::stat(in.path.c_str(), &t) == 0 && t.st_dev == s.st_dev && t.st_ino == s.st_ino) {
        return std::string(name) + " is " + in.what + " ('" + in.path +
               "'): what this command writes there would destroy that input; redirect it elsewhere";
      }
    }
  }
  return "";
}

}  // namespace sempose::cli
