// `sempose` under faults, as a careless or hostile user would run it: outputs on a full disk
// (/dev/full), a FIFO or device where a file is expected, bad --duration values, SIGTERM at
// every phase of start-up, a frames.csv with a negative frame. Each run must end on its own
// (no hang: a watchdog kills it and fails the test), never by a crash signal, with the exit
// code and the message the README promises.
#include <fcntl.h>
#include <grp.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "sempose/hal/pgm.hpp"

namespace {

namespace fs = std::filesystem;

struct Outcome {
  bool exited = false;
  int code = -1;
  int signal = 0;
  bool hung = false;
  double seconds = 0;
  std::string out, err;
};

std::string slurp(const std::string& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::string work_dir() {
  const std::string d = ::testing::TempDir() + "cli_faults_" + std::to_string(::getpid());
  fs::create_directories(d);
  return d;
}

// Runs sempose with args; optionally sends `sig` after `signal_after_ms` (kWhenRunning: once
// it printed its thread placement, i.e. the RT stages run); kills it (and reports a hang)
// after timeout_s.
constexpr int kWhenRunning = -2;
long g_child_file_size_limit = -1;  // RLIMIT_FSIZE of the child in bytes (-1: unlimited)
long g_child_open_files_limit = -1;  // RLIMIT_NOFILE of the child (-1: as inherited)
long g_child_address_space_limit = -1;  // RLIMIT_AS of the child in bytes (-1: as inherited)
long g_child_process_limit = -1;  // RLIMIT_NPROC of the child: its user's threads (-1: as inherited)
int g_child_closed_fd = -1;  // a standard stream the child starts with closed (-1: none)
long g_child_uid = -1;  // the child runs as this user and group (-1: as this process; root ignores RLIMIT_NPROC)
std::string g_child_stdout;  // the child's standard output instead of the capture file ("": captured)
bool g_child_stdout_append = false;  // g_child_stdout opened as the shell's `>>` does (else `>`)
Outcome run(const std::vector<std::string>& args, double timeout_s = 60, int signal_after_ms = -1, int sig = SIGTERM) {
  const std::string dir = work_dir();
  const std::string out_path = dir + "/stdout.txt", err_path = dir + "/stderr.txt";
  // Emptied here, not only by the child: the previous run's output must not be read as this
  // one's (kWhenRunning would signal a child that has not started yet).
  std::ofstream(out_path, std::ios::trunc).close();
  std::ofstream(err_path, std::ios::trunc).close();
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    const int o = ::open(g_child_stdout.empty() ? out_path.c_str() : g_child_stdout.c_str(),
                         O_WRONLY | O_CREAT | (g_child_stdout_append ? O_APPEND : O_TRUNC), 0644);
    const int e = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(o, 1);
    dup2(e, 2);
    const int in = ::open("/dev/null", O_RDONLY);
    dup2(in, 0);
    if (g_child_file_size_limit >= 0) {
      const rlimit lim{static_cast<rlim_t>(g_child_file_size_limit), static_cast<rlim_t>(g_child_file_size_limit)};
      setrlimit(RLIMIT_FSIZE, &lim);
    }
    if (g_child_address_space_limit >= 0) {
      const rlimit lim{static_cast<rlim_t>(g_child_address_space_limit), static_cast<rlim_t>(g_child_address_space_limit)};
      setrlimit(RLIMIT_AS, &lim);
    }
    if (g_child_closed_fd >= 0) ::close(g_child_closed_fd);
    if (g_child_uid >= 0 && (setgroups(0, nullptr) != 0 || setgid(static_cast<gid_t>(g_child_uid)) != 0 ||
                             setuid(static_cast<uid_t>(g_child_uid)) != 0)) {
      _exit(126);
    }
    if (g_child_process_limit >= 0) {
      const rlimit lim{static_cast<rlim_t>(g_child_process_limit), static_cast<rlim_t>(g_child_process_limit)};
      setrlimit(RLIMIT_NPROC, &lim);
    }
    if (g_child_open_files_limit >= 0) {
      const rlimit lim{static_cast<rlim_t>(g_child_open_files_limit), static_cast<rlim_t>(g_child_open_files_limit)};
      setrlimit(RLIMIT_NOFILE, &lim);
    }
    std::vector<char*> argv;
    std::string bin = SEMPOSE_BIN;
    argv.push_back(bin.data());
    std::vector<std::string> copy = args;
    for (auto& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
  Outcome r;
  bool signalled = false;
  for (;;) {
    int status = 0;
    const pid_t w = waitpid(pid, &status, WNOHANG);
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (w == pid) {
      r.exited = WIFEXITED(status);
      r.code = r.exited ? WEXITSTATUS(status) : -1;
      r.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
      r.seconds = el;
      break;
    }
    if (!signalled && signal_after_ms == kWhenRunning && slurp(out_path).find("thread ") != std::string::npos) {
      kill(pid, sig);
      signalled = true;
    }
    if (!signalled && signal_after_ms >= 0 && el * 1000 >= signal_after_ms) {
      kill(pid, sig);
      signalled = true;
    }
    if (el > timeout_s) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      r.hung = true;
      r.seconds = el;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  r.out = slurp(out_path);
  r.err = slurp(err_path);
  return r;
}

// A command line that must be refused: not hung, exit 2, and the error names the problem.
struct Refusal {
  std::vector<std::string> args;
  std::string expect;
};
void expect_refused(const Refusal& c, double timeout_s) {
  const Outcome r = run(c.args, timeout_s);
  std::string joined;
  for (const auto& a : c.args) joined += "'" + a + "' ";
  ASSERT_FALSE(r.hung) << "hung: " << joined;
  EXPECT_EQ(r.code, 2) << joined << "\n" << r.out << r.err;
  EXPECT_NE(r.err.find(c.expect), std::string::npos) << joined << "\n" << r.err;
}

// A small, fast scene: the simulator on its virtual clock (no real-time pacing); `pipeline`:
// more keys of the pipeline section ("stats_period_ms: 100, ").
std::string small_scene(const std::string& pipeline) {
  return "scan: {field_w: 320, field_h: 240, max_roi_w: 128, max_roi_h: 128}\n"
         "sim:\n  clock: virtual\n  targets:\n    - {texture: {source: lamella}, size: [60, 40], start: [160, 120, 0]}\n"
         "tracker: {pattern_size_px: 64, roi_size_px: 96}\n"
         "pipeline: {lock_memory: false, hold_dma_latency: false, " + pipeline + "\n"
         "           acquisition: {cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0},\n"
         "           output: {cpu: -1, priority: 0}, non_rt_cpu: -1}\n";
}

// That scene as a config file, with `extra` sections.
std::string small_config(const std::string& dir, const std::string& extra) {
  static int n = 0;
  const std::string path = dir + "/small" + std::to_string(++n) + ".yaml";
  std::ofstream(path) << small_scene("stats_period_ms: 100,") << extra;
  return path;
}

std::string field(const std::string& text, const std::string& key) {
  const auto p = text.rfind(" " + key + "=");
  if (p == std::string::npos) return "";
  const auto a = p + key.size() + 2;
  return text.substr(a, text.find_first_of(" \n", a) - a);
}

// Which build a lab runs (a bug report, the package against the binary): `sempose --version`
// prints the project's version (there was none, found probing).
TEST(CliFaults, VersionIsPrinted) {
  const Outcome r = run({"--version"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(std::regex_match(r.out, std::regex(R"(sempose \d+\.\d+\.\d+\n)"))) << r.out;  // A stray word after it is refused, not ignored (found probing).
  const Outcome stray = run({"--version", "extra"});
  EXPECT_EQ(stray.code, 2) << stray.out;
  EXPECT_NE(stray.err.find("unexpected argument 'extra' after --version"), std::string::npos) << stray.err;
}

TEST(CliFaults, CsvOnAFullDiskIsReportedAndFailsTheRun) {
  const std::string dir = work_dir();
  const std::string cfg = small_config(dir, "output: {poses_csv: /dev/full}\ncan: {log_file: " + dir + "/can.log}\n");
  const Outcome r = run({"run", "--config", cfg, "--duration", "1"});
  ASSERT_FALSE(r.hung) << r.out << r.err;
  EXPECT_TRUE(r.exited) << "signal " << r.signal;
  EXPECT_EQ(r.code, 4) << r.out << r.err;
  std::printf("CSV on /dev/full: exit %d, output_errors=%s csv_lines_lost=%s\n", r.code,
              field(r.out, "output_errors").c_str(), field(r.out, "csv_lines_lost").c_str());
  EXPECT_NE(field(r.out, "output_errors"), "0");
  EXPECT_NE(field(r.out, "csv_lines_lost"), "0");
  EXPECT_NE(r.out.find("fault: writing an output file failed"), std::string::npos) << r.out;
}

TEST(CliFaults, CandumpLogOnAFullDiskIsReportedAndFailsTheRun) {
  const std::string dir = work_dir();
  const Outcome r = run({"run", "--config", small_config(dir, ""), "--duration", "1", "--can-log", "/dev/full"});
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 4) << r.out << r.err;
  std::printf("candump log on /dev/full: exit %d, output_errors=%s can_log_bytes_lost=%s\n", r.code,
              field(r.out, "output_errors").c_str(), field(r.out, "can_log_bytes_lost").c_str());
  EXPECT_NE(field(r.out, "output_errors"), "0");
}

// The histograms are written at the end of the run; a disk that fills up by then shows only
// when the files are flushed. Both files here lead to /dev/full: the run must say they were
// not written (it printed "histograms: DIR/latency_hist.txt" as if they were) and exit 4.
TEST(CliFaults, HistogramsOnAFullDiskAreReportedAndFailTheRun) {
  // A file-size limit below the histograms' (the CSV and the CAN log to /dev/null): the full
  // disk of a run's end. Reported, exit 4, and no file cut short is left under either name
  // (found probing on a 64 KiB tmpfs: latency_hist.txt cut mid-line without its trailer,
  // latency_hist.json empty): the last whole dump stays as it was.
  const std::string dir = work_dir() + "/full_hist";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir + "/latency_hist.txt") << "OLD TXT\n";
  std::ofstream(dir + "/latency_hist.json") << "{}\n";
  const std::string cfg = small_config(work_dir(), "output: {poses_csv: /dev/null}\ncan: {log_file: /dev/null}\n");
  g_child_file_size_limit = 3000;
  const Outcome r = run({"run", "--config", cfg, "--duration", "1", "--hist-dir", dir});
  g_child_file_size_limit = -1;
  ASSERT_FALSE(r.hung) << r.out << r.err;
  EXPECT_TRUE(r.exited) << "signal " << r.signal;
  EXPECT_EQ(r.code, 4) << r.out << r.err;
  EXPECT_NE(r.err.find("cannot write histograms to " + dir), std::string::npos) << r.err;
  // With the reason (it said "write error" whatever the cause).
  EXPECT_NE(r.out.find("histograms: NOT written to " + dir + " (File too large)"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("histograms not written"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(dir + "/latency_hist.txt"), "OLD TXT\n") << "a histogram cut short in place of the last whole one";
  EXPECT_EQ(slurp(dir + "/latency_hist.json"), "{}\n");
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_NE(e.path().extension(), ".part") << e.path();
  // Without the limit the dump replaces them whole.
  const Outcome ok = run({"run", "--config", cfg, "--duration", "1", "--hist-dir", dir});
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_NE(slurp(dir + "/latency_hist.txt").find("# Max Latencies"), std::string::npos) << slurp(dir + "/latency_hist.txt");
}

TEST(CliFaults, FifoDirectoryOrDeviceAsAPathIsRefusedAtOnce) {
  const std::string dir = work_dir();
  const std::string fifo = dir + "/fifo";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  using Case = Refusal;
  const std::string ok_cfg = small_config(dir, "can: {log_file: " + dir + "/can.log}\n");
  const std::string frames = dir + "/one_frame";
  fs::create_directories(frames);
  sempose::hal::Image img;
  img.width = img.height = 64;
  img.pixels.assign(64 * 64, 100);
  sempose::hal::write_pgm(frames + "/f0.pgm", img);
  const Case cases[] = {
      {{"run", "--config", fifo}, "cannot read the config: it is a FIFO"},
      {{"run", "--config", dir}, "cannot read the config: it is a directory"},
      {{"run", "--config", "/dev/zero"}, "cannot read the config: it is a character device"},
      {{"run", "--config", ok_cfg, "--can-log", fifo}, "--can-log: '" + fifo + "' cannot be written: it is a FIFO"},
      {{"run", "--config", ok_cfg, "--can-log", dir}, "cannot be written: it is a directory"},
      {{"run", "--config", ok_cfg, "--hist-dir", "/dev/null"}, "--hist-dir: '/dev/null' cannot hold histograms"},
      {{"run", "--config", small_config(dir, "output: {poses_csv: " + fifo + "}\n")}, "output.poses_csv: '" + fifo},
      {{"replay", "--frames", frames, "--pattern", fifo, "--out", dir + "/o.csv"}, "not a regular file (a FIFO)"},
      {{"replay", "--frames", frames, "--pattern", "/dev/zero", "--out", dir + "/o.csv"}, "a character device"},
  };
  for (const Case& c : cases) {
    ASSERT_NO_FATAL_FAILURE(expect_refused(c, 20));
  }
  ::unlink(fifo.c_str());
}

TEST(CliFaults, DurationMustBeAFiniteNumberOfSeconds) {
  const std::string dir = work_dir();
  for (const char* d : {"nan", "inf", "1e10", "-1", "-0", "-0.0", "abc", ""}) {  // -0: ran until a signal
    const Outcome r = run({"run", "--config", small_config(dir, ""), "--duration", d}, 20);
    ASSERT_FALSE(r.hung) << d;
    EXPECT_EQ(r.code, 2) << d << "\n" << r.err;
    EXPECT_NE(r.err.find("--duration"), std::string::npos) << d << "\n" << r.err;
  }
}

// SIGTERM at every phase of start-up (config, source and pattern banks, outputs, start, run):
// the process ends on its own within seconds, never by a crash, and an output it wrote is
// never cut mid-line.
TEST(CliFaults, SigtermDuringEachPhaseOfStartUp) {
  const std::string dir = work_dir();
  const std::string csv = dir + "/poses_sig.csv";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + dir + "/sig.log}\n");
  for (int delay_ms : {0, 2, 10, 40, 120, 300, 700, 1500, 3000, kWhenRunning}) {
    fs::remove(csv);
    const Outcome r = run({"run", "--config", cfg, "--duration", "60"}, 30, delay_ms);
    ASSERT_FALSE(r.hung) << "hung after SIGTERM at " << delay_ms << " ms";
    // Signals are blocked from the first line of `sempose run`: every phase stops cleanly with
    // exit 0. Only a signal that lands before main() (exec, dynamic loading) takes the default
    // action — then nothing at all was printed or written.
    const bool before_main = r.signal == SIGTERM && r.out.empty() && !fs::exists(csv);
    EXPECT_TRUE((r.exited && r.code == 0) || before_main)
        << "SIGTERM at " << delay_ms << " ms: exit " << r.code << " signal " << r.signal << "\n" << r.out << r.err;
    std::string phase = "before start";
    if (r.out.find("stopped by SIGTERM during setup") != std::string::npos) phase = "during setup";
    if (r.out.find("thread ") != std::string::npos) phase = "running";
    if (before_main) phase = "before main()";
    if (delay_ms == kWhenRunning) {
      EXPECT_NE(r.out.find("stopped by SIGTERM"), std::string::npos) << r.out;
      EXPECT_NE(r.out.find("summary: "), std::string::npos) << "a stop while running still drains and summarises";
    }
    std::printf("SIGTERM at %4d ms: %s, %s after %.2f s\n", delay_ms, phase.c_str(),
                before_main ? "ended by the signal" : ("exit " + std::to_string(r.code)).c_str(), r.seconds);
    if (fs::exists(csv)) {
      const std::string text = slurp(csv);
      EXPECT_TRUE(text.empty() || text.back() == '\n') << "CSV cut mid-line after SIGTERM at " << delay_ms << " ms";
    }
  }
}

// SIGHUP (the operator's ssh session or terminal closing) stops a run as SIGTERM does: it
// used to kill it with the default action, mid-line in the CSV, the candump log unflushed.
TEST(CliFaults, SighupStopsARunCleanly) {
  const std::string dir = work_dir() + "/hup";
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + dir + "/hup.log}\n");
  for (int delay_ms : {1500, kWhenRunning}) {
    fs::remove(csv);
    const Outcome r = run({"run", "--config", cfg, "--duration", "60"}, 30, delay_ms, SIGHUP);
    ASSERT_FALSE(r.hung) << "hung after SIGHUP at " << delay_ms << " ms";
    EXPECT_TRUE(r.exited && r.code == 0) << "SIGHUP at " << delay_ms << " ms: signal " << r.signal << "\n" << r.out << r.err;
    EXPECT_NE(r.out.find("stopped by SIGHUP"), std::string::npos) << r.out;
    if (delay_ms == kWhenRunning) {
      EXPECT_NE(r.out.find("summary: "), std::string::npos) << r.out;
      const std::string text = slurp(csv);
      EXPECT_TRUE(!text.empty() && text.back() == '\n') << "CSV missing or cut mid-line after SIGHUP";
    }
  }
}

TEST(CliFaults, NegativeOrHugeFrameInFramesCsvIsANamedError) {
  const std::string dir = work_dir() + "/frames_bad";
  fs::create_directories(dir);
  sempose::hal::Image img;
  img.width = 96;
  img.height = 96;
  img.bits = 8;
  img.pixels.assign(96 * 96, 0);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = static_cast<std::uint16_t>((i * 7919) % 251);
  sempose::hal::write_pgm(dir + "/f0.pgm", img);
  sempose::hal::write_pgm(dir + "/f1.pgm", img);
  sempose::hal::Image pat = img;
  pat.width = pat.height = 32;
  pat.pixels.resize(32 * 32);
  sempose::hal::write_pgm(dir + "/../pat.pgm", pat);
  for (const char* row : {"-1,0", "1e300,5", "0,nan", "0,1\n0,2", "99999999999999999999,1", "0,1000", "0,2000"}) {
    std::ofstream(dir + "/frames.csv") << "frame,t_ns\n" << row << "\n1,1000\n";
    const Outcome r = run({"replay", "--frames", dir, "--pattern", dir + "/../pat.pgm", "--out", dir + "/../o.csv"}, 60);
    ASSERT_FALSE(r.hung) << row;
    EXPECT_EQ(r.code, 2) << row << "\n" << r.err;
    EXPECT_NE(r.err.find("frames.csv:"), std::string::npos) << row << "\n" << r.err;
  }
}

}  // namespace

// Bad input to `sempose sim` and `sempose pattern` is exit 2 and creates nothing; an output
// that cannot be made is exit 1.
TEST(CliFaults, SimAndPatternNameBadInputBeforeMakingOutputs) {
  const std::string dir = work_dir() + "/simpat";
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/dir_texture.yaml")
      << "scan: {field_w: 256, field_h: 192}\nsim:\n  targets:\n    - {texture: {path: " << dir
      << ", crop: [0, 0, 10, 10]}, size: [40, 30], start: [100, 100, 0]}\n";
  Outcome r = run({"sim", "--out", dir + "/made", "--frames", "2", "--config", dir + "/dir_texture.yaml"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("is a directory, not a file"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/made")) << "the output folder was made before the input was checked";
  std::ofstream(dir + "/a_file") << "x";
  // A file as --out is bad input, named by the option (it was exit 1 after the scene was built).
  r = run({"sim", "--out", dir + "/a_file", "--frames", "2"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--out: '" + dir + "/a_file' cannot hold the recording: it is a regular file"), std::string::npos) << r.err;
  r = run({"sim", "--out", dir + "/a_file/rec", "--frames", "2"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(slurp(dir + "/a_file"), "x");
  r = run({"pattern", "--frames", dir + "/nowhere", "--center", "100,100", "--size", "32", "--out", dir + "/p.pgm"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/p.pgm"));
}

// small_config's scene recorded by `sim` into DIR/rec (n frames, at dwell_ns when given) and its
// pattern averaged from `average` of them into DIR/p.pgm, as an operator would make them.
::testing::AssertionResult record_with_pattern(const std::string& dir, const std::string& cfg, int frames,
                                               const std::string& dwell_ns = "", int average = 2) {
  std::vector<std::string> sim = {"sim", "--out", dir + "/rec", "--frames", std::to_string(frames), "--config", cfg};
  if (!dwell_ns.empty()) sim.insert(sim.end(), {"--dwell", dwell_ns});
  Outcome r = run(sim, 120);
  if (r.code != 0) return ::testing::AssertionFailure() << "sim: " << r.err;
  r = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--average", std::to_string(average),
           "--out", dir + "/p.pgm"},
          60);
  if (r.code != 0) return ::testing::AssertionFailure() << "pattern: " << r.err;
  return ::testing::AssertionSuccess();
}

// `replay --pattern A --pattern B --config C` whose C schedules the two: the schedule was refused
// against C's own targets (none given: the simulator's one), "1 is not a target index (targets:
// 1)", a count the user never gave, and a repeated index said once per entry (found probing).
// With --pattern it names those targets, and replay checks it against them.
TEST(CliFaults, ReplaysScheduleNamesThePatternTargets) {
  const std::string dir = work_dir() + "/replay_schedule";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 4));
  const auto replay = [&](const std::string& schedule) {
    std::ofstream(dir + "/s.yaml") << "pipeline: {schedule: " << schedule << "}\n";
    return run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--pattern", dir + "/p.pgm", "--config",
                dir + "/s.yaml", "--out", dir + "/poses.csv"},
               60);
  };
  Outcome r = replay("[0, 0, 1, 1, 1]");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("is not a target index"), std::string::npos) << r.err;
  r = replay("[0, 0]");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("pipeline.schedule never names target 1"), std::string::npos) << r.err;
  r = replay("[0, 1, 2, 2]");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("pipeline.schedule names target 2; there are 2"), std::string::npos) << r.err;
  // Without --pattern the schedule is the config's, each index beyond its targets said once.
  std::ofstream(dir + "/s.yaml") << "pipeline: {schedule: [0, 1, 1, 1]}\n";
  r = run({"run", "--config", dir + "/s.yaml", "--duration", "0.1"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  const std::string said = "pipeline.schedule: 1 is not a target index (targets: 1";
  ASSERT_NE(r.err.find(said), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(said, r.err.find(said) + 1), std::string::npos) << "said more than once:\n" << r.err;
}

// `replay --pattern P --config C` replaced C's targets: (their start_area, dwell_ns, masks) without
// the "not used by replay" note it gives for C's other unused keys, and still refused C for a
// mask file named there that it would never open (found probing).
TEST(CliFaults, ReplayWithPatternSaysTheConfigsTargetsAreNotUsed) {
  const std::string dir = work_dir() + "/replay_targets";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 3));
  std::ofstream(dir + "/t.yaml") << "targets:\n  - {name: n, pattern_sets: [{file: p.pgm, mask: gone.pgm}], start_area: [300, 200, 5]}\n";
  Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--config", dir + "/t.yaml", "--out",
                   dir + "/poses.csv"},
                  60);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("not used by replay: targets (1, with their start_area, dwell_ns and masks: --pattern gives the targets)"),
            std::string::npos)
      << r.err;
  // Without --pattern they are the targets, and the missing mask is an error.
  r = run({"replay", "--frames", dir + "/rec", "--config", dir + "/t.yaml", "--out", dir + "/poses2.csv"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("targets[0].pattern_sets[0].mask: '" + dir + "/gone.pgm' is missing"), std::string::npos) << r.err;
}

// A recording of few grey levels (a PGM of maxval 3: a 2-bit detector, a heavily binned ADC):
// `pattern` rounded the frames' mean back to those levels (samples 0/1/2 written under maxval
// 255) and the replay with it tracked nothing (found probing). The mean is written stretched,
// its fractions kept, and said.
TEST(CliFaults, APatternOfFewGreyLevelsKeepsWhatAveragingGained) {
  const std::string dir = work_dir() + "/few_levels";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 20));
  fs::create_directories(dir + "/rec3");
  for (const auto& e : fs::directory_iterator(dir + "/rec")) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() != ".pgm") {
      fs::copy_file(e.path(), dir + "/rec3/" + name);
      continue;
    }
    const sempose::hal::Image img = sempose::hal::read_pgm(e.path().string());
    std::ofstream out(dir + "/rec3/" + name, std::ios::binary);
    out << "P5\n" << img.width << " " << img.height << "\n3\n";
    for (const std::uint16_t v : img.pixels) out.put(static_cast<char>(std::lround(v * 3.0 / 255.0)));
  }
  const Outcome p = run({"pattern", "--frames", dir + "/rec3", "--center", "160,120", "--size", "64", "--average", "10", "--out",
                         dir + "/p3.pgm"});
  ASSERT_EQ(p.code, 0) << p.err;
  EXPECT_NE(p.out.find("the frames use grey levels up to 3 only: the mean written x85"), std::string::npos) << p.out;
  const sempose::hal::Image pat = sempose::hal::read_pgm(dir + "/p3.pgm");
  const std::set<std::uint16_t> levels(pat.pixels.begin(), pat.pixels.end());
  EXPECT_GT(levels.size(), 20u) << "the mean of 10 frames rounded back to the frames' 4 levels";
  const Outcome r = run({"replay", "--frames", dir + "/rec3", "--pattern", dir + "/p3.pgm", "--truth",
                         dir + "/rec3/ground_truth.csv", "--out", dir + "/o.csv"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(field(r.out, "poses_compared"), "0") << "nothing tracked with the pattern of the recording's own frames: " << r.out;
  EXPECT_EQ(field(r.out, "false_tracking"), "0") << r.out;
}

// A recording larger than an address-space limit (ulimit -v) leaves room for is refused at once
// by name (found probing: 7000 frames under 6 GB loaded for 18 s, then "std::bad_alloc" alone).
// Here 2000 links to one 320x240 frame (300 MiB as read) under 512 MiB; no poses' CSV made.
TEST(CliFaults, ARecordingBeyondTheAddressSpaceLimitIsRefusedByName) {
  const std::string dir = work_dir() + "/rlimit_as";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 2));
  fs::create_directories(dir + "/big");
  for (int i = 0; i < 2000; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "/big/frame_%06d.pgm", i);
    fs::create_symlink(dir + "/rec/frame_000000.pgm", dir + name);
  }
  g_child_address_space_limit = 512L << 20;
  const Outcome r = run({"replay", "--frames", dir + "/big", "--pattern", dir + "/p.pgm", "--out", dir + "/out.csv"}, 60);
  g_child_address_space_limit = -1;
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("2000 frames need 292 MiB, more than half of the"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("under its address-space limit (ulimit -v 524288 KiB)"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/out.csv"));
}

// A pattern that is one straight edge (left half black, right half white) leaves the place along
// the edge unknown: the fit's curvature is singular and no σ is measured (0). Its poses, 20 px off
// the lamella it was run on, were TRACKING on σ 0 (found probing: 4 of 20 in replay, 60 a second
// in run). No TRACKING pose without a σ.
TEST(CliFaults, APoseWithoutASigmaIsNeverTracking) {
  const std::string dir = work_dir() + "/edge_pattern";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string cfg = dir + "/edge.yaml";
  std::ofstream(cfg) << "source: sim\nscan: {field_w: 320, field_h: 240, max_roi_w: 192, max_roi_h: 192}\n"
                        "sim:\n  clock: virtual\n  seed: 3\n  targets:\n    - {texture: {source: lamella}, size: [60, 40], "
                        "start: [160, 120, 0], trajectory: {kind: sine, amplitude_x_px: 10, amplitude_y_px: 5, period_s: 2}}\n"
                        "tracker: {pattern_size_px: 64, roi_size_px: 96}\n";
  Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "20", "--config", cfg, "--dwell", "2000"}, 120);
  ASSERT_EQ(r.code, 0) << r.err;
  std::string edge = "P5\n64 64\n255\n";
  for (int i = 0; i < 64 * 64; ++i) edge += static_cast<char>(i % 64 < 32 ? 0 : 255);
  std::ofstream(dir + "/edge.pgm", std::ios::binary) << edge;
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/edge.pgm", "--config", cfg, "--out", dir + "/out.csv"}, 60);
  ASSERT_EQ(r.code, 0) << r.err;
  std::istringstream csv(slurp(dir + "/out.csv"));
  int rows = 0, tracking_without_sigma = 0;
  for (std::string line; std::getline(csv, line);) {
    if (line.rfind("frame", 0) == 0) continue;
    ++rows;
    std::vector<std::string> cell;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cell.push_back(c);
    ASSERT_GE(cell.size(), 12u) << line;
    tracking_without_sigma += cell[6] == "TRACKING" && std::stod(cell[8]) == 0.0;
  }
  EXPECT_EQ(rows, 20);
  EXPECT_EQ(tracking_without_sigma, 0) << "TRACKING poses whose sigma_x_px is 0 (4 before)";
}

// An output path that is the process's standard output or error itself (/dev/stdout,
// /proc/self/fd/2): found probing, the file stdout was redirected to was opened a second time and
// the CSV and the status lines wrote over each other (header gone, torn lines, exit 0). run and
// pattern refuse it by key or option; replay takes /dev/stdout as "-" (its report to stderr).
TEST(CliFaults, AnOutputThatIsTheStandardStreamItselfIsNotWrittenOver) {
  const std::string dir = work_dir() + "/std_streams";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 4));
  Outcome r = run({"run", "--config", small_config(dir, "output: {poses_csv: /dev/stdout}\ncan: {log_file: " + dir + "/can.log}\n"),
                   "--duration", "1"});
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("output.poses_csv: '/dev/stdout' is this process's standard output"), std::string::npos) << r.err;
  r = run({"run", "--config", small_config(dir, "output: {poses_csv: " + dir + "/p.csv}\ncan: {log_file: /proc/self/fd/2}\n"),
           "--duration", "1"});
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("can.log_file: '/proc/self/fd/2' is this process's standard error"), std::string::npos) << r.err;
  r = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--out", "/dev/stdout"});
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("--out '/dev/stdout' is this process's standard output"), std::string::npos) << r.err;
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", "/dev/stdout"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("frame,t_ns,", 0), 0u) << "the CSV's header first on stdout: " << r.out.substr(0, 200);
  EXPECT_EQ(r.out.find("summary:"), std::string::npos) << "the report went to stdout too: " << r.out;
  EXPECT_NE(r.err.find("summary:"), std::string::npos) << r.err;
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", "/dev/stderr"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--out '/dev/stderr' is this process's standard error"), std::string::npos) << r.err;
}

// A target's name with '/' (the config's rule allows it) as view's ROI file name: exit 2 after the
// plot was written (found probing). Escaped now, every name a file of its own. And a pattern
// run and replay refuse is refused here too.
TEST(CliFaults, ViewNamesRoiPicturesOfATargetNamedWithASlash) {
  const std::string dir = work_dir() + "/view_slash";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 2));
  std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status,target\n0,0,160,120,0,0.9,TRACKING,a/b\n"
                                       "0,0,160,120,0,0.9,TRACKING,a%2Fb\n";
  const Outcome vw = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v", "--frames", dir + "/rec"});
  EXPECT_EQ(vw.code, 0) << vw.err;
  EXPECT_TRUE(fs::exists(dir + "/v/roi_000000_a%2Fb.png")) << vw.out;
  EXPECT_TRUE(fs::exists(dir + "/v/roi_000000_a%252Fb.png")) << vw.out;
  // A pattern run and replay refuse (not square, flat) was drawn: refused, nothing written.
  std::ofstream(dir + "/rect.pgm", std::ios::binary) << "P5\n64 32\n255\n" << std::string(64 * 32, '\x40');
  std::ofstream(dir + "/flat.pgm", std::ios::binary) << "P5\n64 64\n255\n" << std::string(64 * 64, '\x09');
  for (const char* bad : {"rect", "flat"}) {
    fs::remove_all(dir + "/w");
    const Outcome r = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/w", "--frames", dir + "/rec", "--pattern",
                           dir + "/" + bad + ".pgm", "--pattern", dir + "/p.pgm"});
    EXPECT_EQ(r.code, 2) << bad << ": " << r.err;
    EXPECT_NE(r.err.find(std::string(bad) == "rect" ? "is 64x32: a pattern is square" : "is flat (every sample 9)"),
              std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir + "/w/track.dat")) << bad;
  }
}

// A report lost on standard output (a full disk; /dev/full here) is said on stderr and the exit
// is 4 (found probing: replay's truth and summary lines, pattern's and view's lines were lost
// with nothing on stderr and exit 0); replay repeats its report there.
TEST(CliFaults, AReportLostOnStandardOutputIsSaid) {
  const std::string dir = work_dir() + "/stdout_full";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 4));
  std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,160,120,0,0.9,TRACKING\n";
  g_child_stdout = "/dev/full";
  const Outcome rp = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/out.csv"});
  const Outcome pt = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--out", dir + "/p2.pgm"});
  const Outcome vw = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v"});
  g_child_stdout.clear();
  EXPECT_EQ(rp.code, 4) << rp.err;
  EXPECT_NE(rp.err.find("sempose replay: standard output: the report could not be written (No space left on device)"),
            std::string::npos) << rp.err;
  EXPECT_NE(rp.err.find("summary: frames=4"), std::string::npos) << "the report repeated on stderr: " << rp.err;
  EXPECT_EQ(pt.code, 4) << pt.err;
  EXPECT_NE(pt.err.find("sempose pattern: standard output: the report could not be written"), std::string::npos) << pt.err;
  EXPECT_EQ(vw.code, 4) << vw.err;
  EXPECT_NE(vw.err.find("sempose view: standard output: the report could not be written"), std::string::npos) << vw.err;
  // sim's line saying what it wrote (the recording itself is whole: exit 4, not 1).
  g_child_stdout = "/dev/full";
  const Outcome sm = run({"sim", "--out", dir + "/rec2", "--frames", "2", "--config", small_config(dir, "")});
  g_child_stdout.clear();
  EXPECT_EQ(sm.code, 4) << sm.err;
  EXPECT_NE(sm.err.find("sempose sim: standard output: the report could not be written"), std::string::npos) << sm.err;
  EXPECT_TRUE(fs::exists(dir + "/rec2/frames.csv"));
}

// A 16 px pattern was refused naming tracker.refine's fit with refinement off (found probing):
// the fit template only matters when tracker.refine.enabled is on.
TEST(CliFaults, ASmallPatternNamesTheRefinementOnlyWhenItIsOn) {
  const std::string dir = work_dir() + "/tiny_pattern";
  fs::create_directories(dir);
  const auto config = [&](bool refine) {
    const std::string path = dir + (refine ? "/on.yaml" : "/off.yaml");
    std::ofstream(path) << "scan: {field_w: 64, field_h: 48, max_roi_w: 32, max_roi_h: 32}\n"
                           "sim:\n  clock: virtual\n  targets:\n    - {texture: {source: lamella}, size: [12, 8], start: [32, 24, 0]}\n"
                           "tracker: {pattern_size_px: 16, roi_size_px: 32, search_downsample: 1, refine: {enabled: "
                        << (refine ? "true" : "false")
                        << "}}\npipeline: {lock_memory: false, hold_dma_latency: false, acquisition: {cpu: -1, priority: 0}, "
                           "correlation: {cpu: -1, priority: 0}, output: {cpu: -1, priority: 0}, non_rt_cpu: -1}\n"
                           "output: {poses_csv: "
                        << dir << "/p.csv}\ncan: {log_file: " << dir << "/c.log}\n";
    return path;
  };
  const Outcome off = run({"run", "--config", config(false), "--duration", "0.2"});
  EXPECT_EQ(off.code, 0) << off.err;
  const Outcome on = run({"run", "--config", config(true), "--duration", "0.2"});
  EXPECT_EQ(on.code, 2) << on.err;
  EXPECT_NE(on.err.find("too few pixels for tracker.refine's fit (tracker.refine.enabled is on"), std::string::npos) << on.err;
}

// "-" as --out: replay writes its poses' CSV to standard output (the report to stderr, so a
// pipe gets CSV only); sim, pattern and view refuse it by name rather than make a file or
// folder called "-".
TEST(CliFaults, DashAsOutIsStandardOutputOrRefused) {
  const std::string dir = work_dir() + "/dash";
  fs::create_directories(dir);
  fs::remove_all("-");
  const std::string cfg = small_config(dir, "");
  ASSERT_TRUE(record_with_pattern(dir, cfg, 4));

  Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", "-"}, 120);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("frame,t_ns,x_px,y_px,phi_deg,score,status", 0), 0u) << r.out;
  EXPECT_EQ(r.out.find("summary:"), std::string::npos) << "the report went into the CSV:\n" << r.out;
  EXPECT_NE(r.err.find("summary: frames="), std::string::npos) << r.err;
  std::size_t lines = 0;
  for (char c : r.out) lines += c == '\n';
  EXPECT_GE(lines, 4u) << r.out;  // the header and a pose per recorded frame

  const std::vector<std::vector<std::string>> refused = {
      {"sim", "--out", "-", "--frames", "2", "--config", cfg},
      {"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--out", "-"},
      {"view", "--poses", dir + "/none.csv", "--out", "-"},
  };
  for (const auto& args : refused) {
    r = run(args, 60);
    EXPECT_EQ(r.code, 2) << args[0] << ": " << r.err;
    EXPECT_NE(r.err.find("--out '-' (standard output) is not supported"), std::string::npos) << args[0] << ": " << r.err;
    EXPECT_FALSE(fs::exists("-")) << args[0] << " made a file or folder called '-'";
  }
  r = run({"run", "--config", small_config(dir, "output: {poses_csv: '-'}\n"), "--duration", "1"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("output.poses_csv"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("standard output"), std::string::npos) << r.err;
  // The histograms' folder too: '-' made a folder called '-' (found probing).
  for (const auto& [args, key] : {std::pair{std::vector<std::string>{"run", "--config", small_config(dir, ""), "--duration", "1", "--hist-dir", "-"}, "--hist-dir"},
                                  std::pair{std::vector<std::string>{"run", "--config", small_config(dir, "output: {hist_dir: '-'}\n"), "--duration", "1"}, "output.hist_dir"}}) {
    r = run(args, 60);
    EXPECT_EQ(r.code, 2) << key << ": " << r.err;
    EXPECT_NE(r.err.find(key), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("is not a folder"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists("-")) << key << " made a folder called '-'";
  }
}

// Patterns the tracker cannot use are refused at setup by what is wrong with them (exit 2,
// no output file): a flat one, one whose only detail is a 1-px checkerboard (the prefilter and
// the binned search level average it to flat: it used to be called "flat" too), a
// non-square one, a mask of another size and a mask that leaves too little.
TEST(CliFaults, UntrackablePatternsAreRefusedByName) {
  const std::string dir = work_dir() + "/badpat";
  fs::create_directories(dir + "/frames");
  sempose::hal::Image frame;
  frame.width = 320;
  frame.height = 240;
  frame.pixels.resize(320 * 240);
  for (std::size_t i = 0; i < frame.pixels.size(); ++i) frame.pixels[i] = static_cast<std::uint16_t>((i * 7919) % 251);
  sempose::hal::write_pgm(dir + "/frames/f0.pgm", frame);
  auto image = [&](const std::string& name, int w, int h, auto value) {
    sempose::hal::Image img;
    img.width = w;
    img.height = h;
    img.pixels.resize(static_cast<std::size_t>(w) * h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) img.pixels[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint16_t>(value(x, y));
    sempose::hal::write_pgm(dir + "/" + name, img);
    return dir + "/" + name;
  };
  const std::string flat = image("flat.pgm", 64, 64, [](int, int) { return 100; });
  const std::string checker = image("checker.pgm", 64, 64, [](int x, int y) { return (x + y) % 2 ? 200 : 20; });
  const std::string rect = image("rect.pgm", 64, 32, [](int x, int) { return x * 3; });
  const std::string good = image("good.pgm", 64, 64, [](int x, int y) { return (x / 8 + y / 8) % 2 ? 200 : 20; });
  const std::string mask_small = image("mask_small.pgm", 32, 32, [](int, int) { return 255; });
  const std::string mask_dot = image("mask_dot.pgm", 64, 64, [](int x, int y) { return x == 32 && y == 32 ? 255 : 0; });
  struct Case {
    std::vector<std::string> pattern_args;
    std::string expect;
  };
  const Case cases[] = {
      {{"--pattern", flat}, "flat (constant grey level)"},
      {{"--pattern", checker}, "only at the pixel scale"},
      {{"--pattern", rect}, "64x32; patterns must be square"},
      {{"--pattern", good, "--mask", mask_small}, "the shape mask is 32x32, the pattern 64x64"},
      {{"--pattern", good, "--mask", mask_dot}, "the shape mask leaves under 64 pixels"},
  };
  const std::string cfg = small_config(dir, "");
  for (const Case& c : cases) {
    std::vector<std::string> args = {"replay", "--frames", dir + "/frames", "--config", cfg};
    args.insert(args.end(), c.pattern_args.begin(), c.pattern_args.end());
    args.insert(args.end(), {"--out", dir + "/o.csv"});
    const Outcome r = run(args, 60);
    ASSERT_FALSE(r.hung) << c.expect;
    EXPECT_EQ(r.code, 2) << c.expect << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
    // And the file it is about (found probing: only "pattern set 0" was named).
    EXPECT_NE(r.err.find(c.pattern_args.back()), std::string::npos) << "the file is not named:\n" << r.err;
    EXPECT_FALSE(fs::exists(dir + "/o.csv")) << "output made before the pattern was refused: " << c.expect;
  }
  // On the simulator the user wrote no pattern: one recorded flat from a clipped scene names the
  // keys that clip it (found probing: `sim.output_offset: 1` said only "the pattern is flat").
  const std::string clipped = dir + "/clipped.yaml";
  std::ofstream(clipped) << "scan: {field_w: 320, field_h: 240, max_roi_w: 128, max_roi_h: 128}\n"
                            "sim:\n  clock: virtual\n  output_offset: 1\n"
                            "  targets:\n    - {texture: {source: lamella}, size: [60, 40], start: [160, 120, 0]}\n"
                            "tracker: {pattern_size_px: 64, roi_size_px: 96}\n"
                            "output: {poses_csv: " << dir << "/clipped.csv}\n";
  const Outcome r = run({"run", "--config", clipped, "--duration", "1"}, 60);
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("flat (constant grey level)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("sim.output_offset 1 + sim.output_white 0.85"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/clipped.csv")) << "output made before the pattern was refused";
}

// An option given twice is refused by name (exit 2, nothing made) rather than the later one
// silently winning; the repeatable ones (--pattern, replay's --mask) still repeat.
TEST(CliFaults, AnOptionGivenTwiceIsRefusedByName) {
  const std::string dir = work_dir() + "/twice";
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "");
  const std::vector<std::vector<std::string>> refused = {
      {"sim", "--out", dir + "/rec", "--frames", "3", "--frames", "4", "--config", cfg},
      {"pattern", "--frames", dir, "--center", "1,1", "--out", dir + "/p.pgm", "--center", "2,2"},
      {"replay", "--frames", dir, "--pattern", dir + "/p.pgm", "--out", dir + "/a.csv", "--out", dir + "/b.csv"},
      {"run", "--config", cfg, "--duration", "1", "--duration", "2"},
      {"check-rt", "--config", cfg, "--config", cfg},
      {"view", "--poses", dir + "/p.csv", "--out", dir + "/v", "--every", "2", "--every", "3"},
  };
  for (const auto& args : refused) {
    const Outcome r = run(args, 60);
    EXPECT_EQ(r.code, 2) << args[0] << ": " << r.err;
    EXPECT_NE(r.err.find("is given twice"), std::string::npos) << args[0] << ": " << r.err;
  }
  EXPECT_FALSE(fs::exists(dir + "/rec")) << "sim made its output before refusing";
  EXPECT_FALSE(fs::exists(dir + "/v")) << "view made its output before refusing";

  ASSERT_TRUE(record_with_pattern(dir, cfg, 3));
  const Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--pattern", dir + "/p.pgm", "--out",
           dir + "/two.csv"},
          120);
  EXPECT_EQ(r.err.find("is given twice"), std::string::npos) << "--pattern is repeatable: " << r.err;
}

// A simulated target that never enters the field (a typo in `start:`) used to give a recording
// of background without a word; sim now says which target and on how many frames it is seen.
TEST(CliFaults, SimSaysWhenATargetIsNotInTheField) {
  const std::string dir = work_dir() + "/outside";
  fs::create_directories(dir);
  std::ofstream(dir + "/out.yaml") << "scan: {field_w: 320, field_h: 240}\nsim:\n  targets:\n"
                                      "    - {texture: {source: lamella}, size: [60, 40], start: [3000, 120, 0]}\n";
  Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "2", "--config", dir + "/out.yaml"}, 60);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("target 0 (start [3000, 120]) is in the 320x240 field on 0 of 2 frames"), std::string::npos)
      << r.err;
  r = run({"sim", "--out", dir + "/in", "--frames", "2", "--config", small_config(dir, "")}, 60);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
}

// `pattern --out` inside the frames folder: a PGM there is read as a frame by the next replay
// or pattern, and one named like a frame overwrote the recording (found probing: the first
// frame became the 128² pattern). Refused by name, nothing written.
TEST(CliFaults, PatternIsNotWrittenIntoTheFramesFolder) {
  const std::string dir = work_dir() + "/into";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 2));
  const auto before = fs::file_size(dir + "/rec/frame_000000.pgm");
  for (const std::string& out : {dir + "/rec/frame_000000.pgm", dir + "/rec/./p.pgm"}) {
    const Outcome r =
        run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--out", out}, 60);
    EXPECT_EQ(r.code, 2) << out << ": " << r.err;
    EXPECT_NE(r.err.find("is in the frames folder"), std::string::npos) << r.err;
  }
  EXPECT_EQ(fs::file_size(dir + "/rec/frame_000000.pgm"), before) << "a frame of the recording was overwritten";
  EXPECT_FALSE(fs::exists(dir + "/rec/p.pgm"));
}

// `sim --out` on an earlier recording: a shorter new one left the old frames beside its own
// (found probing: 8 frames, then 3 — the next replay failed on "frame 3 has no t_ns row").
// Refused by name; the old recording is left as it was.
TEST(CliFaults, SimDoesNotWriteOverARecording) {
  const std::string dir = work_dir() + "/over";
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "");
  Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "4", "--config", cfg}, 60);
  ASSERT_EQ(r.code, 0) << r.err;
  r = run({"sim", "--out", dir + "/rec", "--frames", "2", "--config", cfg}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("already holds a recording (4 PGM frames"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/rec/frame_000003.pgm"));
  fs::create_directories(dir + "/empty");
  r = run({"sim", "--out", dir + "/empty", "--frames", "2", "--config", cfg}, 60);
  EXPECT_EQ(r.code, 0) << "an existing empty folder is fine: " << r.err;
}

// `sempose run` on a recording: the frames set the field, whatever scan.field_w/h says; the
// start-up line gives the field and a note says when the config's differs (it used to be
// ignored without a word).
TEST(CliFaults, RunOnARecordingSaysWhichFieldItUses) {
  const std::string dir = work_dir() + "/field";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 3));
  std::ofstream(dir + "/run.yaml") << "scan: {field_w: 640, field_h: 480}\nsource: replay\nreplay: {frames_dir: " << dir
                                   << "/rec}\ntargets: [{name: a, pattern_sets: [{file: " << dir
                                   << "/p.pgm}]}]\noutput: {poses_csv: " << dir << "/poses.csv}\ncan: {log_file: " << dir
                                   << "/can.log}\npipeline: {lock_memory: false, hold_dma_latency: false, acquisition: "
                                      "{cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0}, output: {cpu: -1, "
                                      "priority: 0}, non_rt_cpu: -1}\n";
  const Outcome r = run({"run", "--config", dir + "/run.yaml", "--duration", "5"}, 60);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("source replay (virtual time), 320x240 field"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("note: the field is the source's 320x240, not scan.field_w/h 640x480"), std::string::npos) << r.out;
}

// A run on a recording writes no PGM among its frames (found probing: output.poses_csv
// REC/frame_999999.pgm ran, exit 0, and every replay of REC after failed on its "wrong magic";
// --can-log REC/zz.pgm the same). Refused by name before anything is written; the replay after
// still reads the recording.
TEST(CliFaults, RunWritesNoPgmIntoTheRecordingItReads) {
  const std::string dir = work_dir() + "/run_into_rec";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 3));
  const std::string rec = dir + "/rec";
  const auto frames_in_rec = [&] {
    int n = 0;
    for (const auto& e : fs::directory_iterator(rec)) n += e.path().extension() == ".pgm";
    return n;
  };
  const int frames = frames_in_rec();
  const auto config = [&](const std::string& csv, const std::string& log) {
    const std::string path = dir + "/run_" + std::to_string(frames_in_rec()) + fs::path(csv).stem().string() + ".yaml";
    std::ofstream(path) << "source: replay\nreplay: {frames_dir: " << rec << "}\ntargets: [{name: a, pattern_sets: [{file: " << dir
                        << "/p.pgm}]}]\noutput: {poses_csv: " << csv << "}\ncan: {log_file: " << log
                        << "}\npipeline: {lock_memory: false, hold_dma_latency: false, acquisition: {cpu: -1, priority: 0}, "
                           "correlation: {cpu: -1, priority: 0}, output: {cpu: -1, priority: 0}, non_rt_cpu: -1}\n";
    return path;
  };
  Outcome r = run({"run", "--config", config(rec + "/frame_999999.pgm", dir + "/can.log"), "--duration", "5"}, 60);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("output.poses_csv: '" + rec + "/frame_999999.pgm' is a PGM in the recording's frames folder"), std::string::npos)
      << r.err;
  r = run({"run", "--config", config(dir + "/poses.csv", dir + "/can.log"), "--can-log", rec + "/zz.pgm", "--duration", "5"}, 60);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("--can-log: '" + rec + "/zz.pgm' is a PGM in the recording's frames folder"), std::string::npos) << r.err;
  EXPECT_EQ(frames_in_rec(), frames) << "a PGM was written among the frames";
  // Another name in the folder, or a PGM beside it, is no frame: runs.
  r = run({"run", "--config", config(dir + "/poses.pgm", rec + "/can.log"), "--duration", "5"}, 60);
  EXPECT_EQ(r.code, 0) << r.err;
}

// Hostile option values (found probing the six commands): each used to run with something the
// operator did not mean — `check-rt --config ''` checked the built-in defaults, `--hist-dir
// --strict-rt` ran without --strict-rt and wrote into a folder called "--strict-rt", a hex
// `--duration 0x1` ran 1 s, `--seed ' -1'` seeded 2^64-1, a hex `--center` was read, an empty
// `--frames`/`--config` dropped that input, a second `--mask` replaced the first, and a `--dwell`
// outside the scan limits made the output folder before failing. Now exit 2
// with the option and the value named, before anything is written.
TEST(CliFaults, HostileOptionValuesAreRefusedByName) {
  const std::string dir = work_dir() + "/hostile_opts";
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "");
  ASSERT_TRUE(record_with_pattern(dir, cfg, 2));
  {
    std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,1,160,120,0,0.9,TRACKING\n";
    sempose::hal::Image mask;
    mask.width = mask.height = 32;
    mask.pixels.assign(32 * 32, 255);
    sempose::hal::write_pgm(dir + "/mask32.pgm", mask);
    mask.width = mask.height = 64;
    mask.pixels.assign(64 * 64, 255);
    sempose::hal::write_pgm(dir + "/mask64.pgm", mask);
  }
  const std::string rec = dir + "/rec", pat = dir + "/p.pgm", out = dir + "/out";
  using Case = Refusal;
  const Case cases[] = {
      {{"check-rt", "--config", ""}, "--config: the value is empty"},
      {{"run", "--config", cfg, "--duration", "0.2", "--hist-dir", "--strict-rt"},
       "--hist-dir needs a value (the next word is the option --strict-rt)"},
      {{"run", "--config", cfg, "--duration", "0x1"}, "--duration: '0x1' is not a finite number of seconds in [0, 315576000]"},
      {{"run", "--config", cfg, "--duration", "1", "--can-log", ""}, "--can-log: the value is empty"},
      {{"sim", "--out", out, "--frames", "1", "--seed", " -1", "--config", cfg},
       "--seed: ' -1' is not a whole number in [0, 18446744073709551615]"},
      {{"sim", "--out", out, "--frames=1", "--config", cfg}, "give the value after a space: --frames 1"},
      // In range for the option, outside the config's scan limits: found before the folder is made.
      {{"sim", "--out", out, "--frames", "1", "--dwell", "1", "--config", cfg},
       "--dwell: 1 ns is outside the scan limits [100, 10000] ns"},
      {{"sim", "--out", out, "--frames", "12abc", "--config", cfg}, "--frames: '12abc' is not a whole number in [1, 1000000]"},
      {{"pattern", "--frames", rec, "--center", "0xA0,0x78", "--size", "64", "--out", out}, "--center '0xA0,0x78' is not X,Y"},
      {{"view", "--poses", dir + "/poses.csv", "--out", out, "--frames", ""}, "--frames: the value is empty"},
      {{"view", "--poses", dir + "/poses.csv", "--out", out, "--every", "inf"}, "--every: 'inf' is not a whole number in [1, 1000000]"},
      {{"replay", "--frames", rec, "--pattern", pat, "--config", "", "--out", out}, "--config: the value is empty"},
      {{"replay", "--frames", rec, "--pattern", pat, "--mask", dir + "/mask32.pgm", "--mask", dir + "/mask64.pgm", "--out", out},
       "both follow --pattern '" + pat + "': one mask per pattern"},
  };
  for (const Case& c : cases) {
    ASSERT_NO_FATAL_FAILURE(expect_refused(c, 60));
    EXPECT_FALSE(fs::exists(out)) << c.expect << ": output made";
    EXPECT_FALSE(fs::exists("--strict-rt")) << c.expect << ": a folder called --strict-rt was made";
    fs::remove_all(out);
    fs::remove_all("--strict-rt");
  }
}

// An output that names one of the command's inputs: each used to exit 0 having written over
// the input (found probing: replay's CSV over its pattern, the recording's frames.csv or a
// frame, its --truth; run's CAN log over its config; the CAN log and the poses into one file;
// the poses or the CAN log named like a histogram file in the histogram folder; view's poses
// named like a file view writes into its --out; the recording's ground_truth.csv).
TEST(CliFaults, AnOutputThatIsAnInputIsRefused) {
  const std::string dir = work_dir() + "/out_is_in";
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "");
  ASSERT_TRUE(record_with_pattern(dir, cfg, 2));
  const std::string rec = dir + "/rec", pat = dir + "/p.pgm";
  const std::string pattern_bytes = slurp(pat), frames_csv = slurp(rec + "/frames.csv"), frame1 = slurp(rec + "/frame_000001.pgm"),
                    truth = slurp(rec + "/ground_truth.csv"), config = slurp(cfg);
  const std::string self = dir + "/self.yaml";  // a config whose poses CSV is the config itself
  std::ofstream(self) << config << "output: {poses_csv: " << self << "}\n";
  const std::string self_text = slurp(self);
  using Case = Refusal;
  const Case cases[] = {
      {{"replay", "--frames", rec, "--pattern", pat, "--out", pat}, "--out '" + pat + "' is the pattern of target 0"},
      {{"replay", "--frames", rec, "--pattern", pat, "--out", rec + "/frames.csv"}, "is the time stamps of --frames"},
      {{"replay", "--frames", rec, "--pattern", pat, "--out", rec + "/frame_000001.pgm"}, "is a frame of --frames"},
      {{"replay", "--frames", rec, "--pattern", pat, "--truth", rec + "/ground_truth.csv", "--out", rec + "/../rec/ground_truth.csv"},
       "is --truth"},
      {{"replay", "--frames", rec, "--pattern", pat, "--out", rec + "/poses.pgm"}, "is a PGM in the frames folder"},
      // The recording's own truth, not given as --truth: the next `replay --truth` read poses.
      {{"replay", "--frames", rec, "--pattern", pat, "--out", rec + "/ground_truth.csv"}, "is the ground truth of --frames"},
      {{"run", "--config", cfg, "--duration", "0.2", "--can-log", cfg}, "--can-log '" + cfg + "' is the config"},
      {{"run", "--config", self, "--duration", "0.2"}, "output.poses_csv '" + self + "' is the config"},
      {{"run", "--config", small_config(dir, "output: {poses_csv: " + dir + "/both.txt}\ncan: {log_file: " + dir + "/both.txt}\n"),
        "--duration", "0.2"},
       "can.log_file: '" + dir + "/both.txt' is also output.poses_csv"},
      // The histograms' own names in the histogram folder: written over the CSV or log at exit.
      {{"run", "--config",
        small_config(dir, "output: {poses_csv: " + dir + "/h/latency_hist.txt, hist_dir: " + dir + "/h}\ncan: {log_file: " +
                              dir + "/h/can.log}\n"),
        "--duration", "0.2"},
       "output.poses_csv: '" + dir + "/h/latency_hist.txt' is the histogram file"},
      {{"run", "--config", cfg, "--duration", "0.2", "--hist-dir", dir + "/h", "--can-log", dir + "/h/latency_hist.json"},
       "--can-log: '" + dir + "/h/latency_hist.json' is the histogram file"},
      // The name the dump writes first: truncated by it, then renamed away (found probing).
      {{"run", "--config", cfg, "--duration", "0.2", "--hist-dir", dir + "/h", "--can-log", dir + "/h/latency_hist.txt.part"},
       "--can-log: '" + dir + "/h/latency_hist.txt.part' is the histogram file"},
      // '-' as the CAN log made a file named '-' (the poses' '-' was refused by name).
      {{"run", "--config", cfg, "--duration", "0.2", "--can-log", "-"}, "--can-log: '-' (standard output) is not supported"},
      {{"run", "--config", small_config(dir, "can: {log_file: '-'}\n"), "--duration", "0.2"},
       "can.log_file: '-' (standard output) is not supported"},
      // The histogram folder named as the CSV, or inside the CAN log: made at start, the folder
      // could not be made at exit (the whole run went, then "histograms: NOT written", exit 4).
      {{"run", "--config", small_config(dir, "output: {poses_csv: " + dir + "/hp.csv}\n"), "--duration", "0.2", "--hist-dir",
        dir + "/hp.csv"},
       "--hist-dir: '" + dir + "/hp.csv' is output.poses_csv"},
      {{"run", "--config", cfg, "--duration", "0.2", "--can-log", dir + "/hc.log", "--hist-dir", dir + "/hc.log/h"},
       "--hist-dir: '" + dir + "/hc.log/h' lies inside --can-log"},
      // view's own output names in --out: the poses CSV became the plot's data.
      {{"view", "--poses", dir + "/track.dat", "--out", dir}, "--poses '" + dir + "/track.dat' is in --out"},
      {{"view", "--poses", dir + "/roi_000000.png", "--out", dir + "/."}, "under a name view writes (roi_000000.png)"},
  };
  std::ofstream(dir + "/track.dat") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,1,2,3,4,0.5,TRACKING\n";
  std::ofstream(dir + "/roi_000000.png") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,1,2,3,4,0.5,TRACKING\n";
  const std::string view_input = slurp(dir + "/track.dat");
  fs::create_directories(dir + "/h");
  for (const Case& c : cases) {
    ASSERT_NO_FATAL_FAILURE(expect_refused(c, 60));
  }
  EXPECT_TRUE(fs::is_empty(dir + "/h")) << "an output was made before the histogram clash was refused";
  EXPECT_EQ(slurp(dir + "/track.dat"), view_input);
  EXPECT_EQ(slurp(dir + "/roi_000000.png"), view_input);
  EXPECT_EQ(slurp(pat), pattern_bytes);
  EXPECT_EQ(slurp(rec + "/frames.csv"), frames_csv);
  EXPECT_EQ(slurp(rec + "/frame_000001.pgm"), frame1);
  EXPECT_EQ(slurp(rec + "/ground_truth.csv"), truth);
  EXPECT_EQ(slurp(cfg), config);
  EXPECT_EQ(slurp(self), self_text);
  EXPECT_FALSE(fs::exists(rec + "/poses.pgm"));
  EXPECT_FALSE(fs::exists(dir + "/both.txt"));
  EXPECT_FALSE(fs::exists(dir + "/hp.csv"));
  EXPECT_FALSE(fs::exists(dir + "/hc.log"));
  // A CSV beside the recording (not one of its files) is fine.
  const Outcome ok = run({"replay", "--frames", rec, "--pattern", pat, "--out", rec + "/poses.csv"}, 120);
  EXPECT_EQ(ok.code, 0) << ok.err;
}

// A config whose scan: (or sim:) section is given twice: sim used the first and ignored the
// second without a word (found probing; run and check-rt refused it). Now named, nothing made.
TEST(CliFaults, SimRefusesASectionGivenTwice) {
  const std::string dir = work_dir() + "/dup_section";
  fs::create_directories(dir);
  std::ofstream(dir + "/dup.yaml") << "scan: {field_w: 320, field_h: 240}\nscan: {field_w: 640, field_h: 480}\n";
  const Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "1", "--config", dir + "/dup.yaml"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("dup.yaml:2:1: scan: duplicate key (first given on line 1)"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/rec"));
}

// `sempose sim` looked for a texture given by a relative path in the data folders only, not beside
// its config as `sempose run` does (README, Configuration): a texture of the user's own beside the
// config was "not found", and one named as the built-in micrograph is (data/sem/...) was silently
// replaced by the built-in: a recording of another scene than `run` tracks (found probing).
TEST(CliFaults, SimFindsATextureBesideItsConfigAsRunDoes) {
  const std::string dir = work_dir() + "/beside";
  fs::remove_all(dir);
  fs::create_directories(dir + "/data/sem");
  const auto write_texture = [](const std::string& file) {  // bright diagonal bands: no built-in looks so
    std::ofstream f(file, std::ios::binary);
    f << "P5\n200 200\n255\n";
    for (int y = 0; y < 200; ++y)
      for (int x = 0; x < 200; ++x) f.put(static_cast<char>(((x + y) / 10) % 2 ? 230 : 20));
  };
  write_texture(dir + "/data/sem/needle_contact_eb.pgm");
  write_texture(dir + "/own.pgm");
  const auto config = [&](const std::string& name, const std::string& texture) {
    std::ofstream(dir + "/" + name) << "scan: {field_w: 320, field_h: 240, max_roi_w: 160, max_roi_h: 160}\n"
                                       "sim:\n  clock: virtual\n  targets:\n"
                                       "    - {texture: {source: image, path: " << texture
                                    << ", crop: [0, 0, 120, 160], mask: full}, size: [90, 120], start: [160, 120, 0]}\n";
    return dir + "/" + name;
  };
  const auto frame = [&](const std::string& cfg, const std::string& out) {
    const Outcome r = run({"sim", "--out", dir + "/" + out, "--frames", "1", "--seed", "3", "--config", cfg}, 60);
    EXPECT_EQ(r.code, 0) << cfg << "\n" << r.err;
    return slurp(dir + "/" + out + "/frame_000000.pgm");
  };
  const std::string relative = frame(config("rel.yaml", "data/sem/needle_contact_eb.pgm"), "rel");
  const std::string absolute = frame(config("abs.yaml", dir + "/data/sem/needle_contact_eb.pgm"), "abs");
  ASSERT_FALSE(relative.empty());
  EXPECT_TRUE(relative == absolute) << "the relative path did not take the texture beside the config";
  frame(config("own.yaml", "own.pgm"), "own");
  const Outcome r = run({"sim", "--out", dir + "/none", "--frames", "1", "--config", config("none.yaml", "none.pgm")}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("sim.targets[0].texture.path: none.pgm: not found (tried: " + dir + "/none.pgm"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/none"));
}

// Two sims into one folder at once both passed the "already holds a recording" check and mixed
// their frames under one run's frames.csv and truth (found probing). The folder is locked while
// recorded: the second is refused by name. The other recorder here is this test.
TEST(CliFaults, SimIntoAFolderAnotherSimRecordsIsRefused) {
  const std::string dir = work_dir() + "/sim_lock";
  fs::create_directories(dir + "/rec");
  const int held = ::open((dir + "/rec").c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  ASSERT_GE(held, 0);
  ASSERT_EQ(::flock(held, LOCK_EX | LOCK_NB), 0);
  const Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "2", "--config", small_config(dir, "")}, 60);
  ::close(held);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--out '" + dir + "/rec' is being recorded by another sim"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_empty(dir + "/rec"));
  const Outcome ok = run({"sim", "--out", dir + "/rec", "--frames", "2", "--config", small_config(dir, "")}, 60);
  EXPECT_EQ(ok.code, 0) << ok.err;
}

// A FIFO where replay writes its CSV or reads its truth, or where view reads its poses: each
// blocked in open() for ever (found probing); a directory as --truth was read as a truth of no
// rows (exit 0, nothing compared). Refused by name at once.
TEST(CliFaults, FifoOrDirectoryAsReplayOrViewFileIsRefusedAtOnce) {
  const std::string dir = work_dir() + "/fifo_files";
  fs::create_directories(dir);
  const std::string fifo = dir + "/fifo";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 2));
  const std::string rec = dir + "/rec", pat = dir + "/p.pgm";
  using Case = Refusal;
  const Case cases[] = {
      {{"replay", "--frames", rec, "--pattern", pat, "--out", fifo}, "--out: '" + fifo + "' cannot be written: it is a FIFO"},
      {{"replay", "--frames", rec, "--pattern", pat, "--truth", fifo, "--out", dir + "/o.csv"}, "--truth: '" + fifo + "' is a FIFO"},
      {{"replay", "--frames", rec, "--pattern", pat, "--truth", rec, "--out", dir + "/o.csv"}, "--truth: '" + rec + "' is a directory"},
      {{"view", "--poses", fifo, "--out", dir + "/v"}, "--poses: '" + fifo + "' is a FIFO"},
  };
  for (const Case& c : cases) {
    ASSERT_NO_FATAL_FAILURE(expect_refused(c, 20));
  }
  EXPECT_FALSE(fs::exists(dir + "/o.csv"));
  EXPECT_FALSE(fs::exists(dir + "/v"));
  ::unlink(fifo.c_str());
}

// A top-level key that no part of sempose reads (a typo, the wrong case) was ignored by `sim`,
// which then recorded the default scene (exit 0). Refused naming the file, line, key and the
// keys allowed; a run config's other sections (tracker:, output:, ...) are still accepted.
TEST(CliFaults, SimRefusesAnUnknownTopLevelKey) {
  const std::string dir = work_dir() + "/sim_unknown";
  fs::create_directories(dir);
  const std::string scene = "  - {texture: {source: lamella}, size: [60, 40], start: [160, 120, 0]}\n";
  std::ofstream(dir + "/typo.yaml") << "scan: {field_w: 320, field_h: 240}\nsim_targets:\n" << scene;
  std::ofstream(dir + "/case.yaml") << "scan: {field_w: 320, field_h: 240}\nSim:\n  targets:\n" << scene;
  std::ofstream(dir + "/nested.yaml") << "scan: {field_w: 320, feld_h: 240}\n";
  const Refusal cases[] = {
      {{"sim", "--out", dir + "/rec", "--frames", "1", "--config", dir + "/typo.yaml"},
       "typo.yaml:2:1: sim_targets: unknown key (known: source, scan, sim, replay"},
      {{"sim", "--out", dir + "/rec", "--frames", "1", "--config", dir + "/case.yaml"}, "case.yaml:2:1: Sim: unknown key"},
      {{"sim", "--out", dir + "/rec", "--frames", "1", "--config", dir + "/nested.yaml"}, "scan.feld_h: unknown key"},
  };
  for (const Refusal& c : cases) ASSERT_NO_FATAL_FAILURE(expect_refused(c, 60));
  EXPECT_FALSE(fs::exists(dir + "/rec"));
  // A full run config (sections sim does not read) still records.
  const Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "1", "--config",
                         small_config(dir, "output: {poses_csv: x.csv}\ncan: {log_file: x.log}\n")},
                        60);
  EXPECT_EQ(r.code, 0) << r.err;
}

// replay --out in a folder that does not exist: the CSV's open() failed after setup with
// "output.poses_csv: cannot create …", a config key the user never wrote. Named by the option
// and the path, before any work.
TEST(CliFaults, ReplayOutInAMissingFolderNamesTheOption) {
  const std::string dir = work_dir() + "/replay_missing_dir";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 2));
  const std::string out = dir + "/no_such_dir/poses.csv";
  const Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", out}, 60);
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--out: '" + out + "' cannot be written: its folder '" + dir + "/no_such_dir' does not exist"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("output.poses_csv"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("pattern bank"), std::string::npos) << "refused before the setup:\n" << r.err;
  EXPECT_FALSE(fs::exists(dir + "/no_such_dir"));
}

// A FIFO in the place of a recording's ground_truth.csv blocked replay (and run on the
// recording) in open() for ever; a directory there read as a truth of no rows. Refused by name.
TEST(CliFaults, RecordingTruthThatIsAFifoOrDirectoryIsRefusedAtOnce) {
  const std::string dir = work_dir() + "/truth_fifo";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 2));
  const std::string truth = dir + "/rec/ground_truth.csv";
  ASSERT_EQ(::unlink(truth.c_str()), 0);
  ASSERT_EQ(::mkfifo(truth.c_str(), 0600), 0);
  const Refusal fifo{{"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/o.csv"},
                     truth + ": not a regular file (a FIFO)"};
  ASSERT_NO_FATAL_FAILURE(expect_refused(fifo, 20));
  ::unlink(truth.c_str());
  fs::create_directories(truth);
  const Refusal directory{{"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/o.csv"},
                          truth + ": not a regular file (a directory)"};
  ASSERT_NO_FATAL_FAILURE(expect_refused(directory, 20));
  EXPECT_FALSE(fs::exists(dir + "/o.csv"));
}

// A file-size limit (`ulimit -f`) reached by the CSV: SIGXFSZ's default action killed `run`
// mid-line (signal 25: a cut CSV line, no summary) and `replay` likewise. Now the write fails
// (EFBIG) and is reported as any failed output: exit 4, counted, the CSV cut to whole lines.
TEST(CliFaults, AFileSizeLimitIsAWriteErrorNotADeath) {
  const std::string dir = work_dir() + "/fsize";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 10));  // ~1.2 kB of replay CSV
  const std::string csv = dir + "/poses.csv", replay_csv = dir + "/replay.csv";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: /dev/null}\n");
  g_child_file_size_limit = 16384;
  Outcome r = run({"run", "--config", cfg, "--duration", "2"}, 60);
  g_child_file_size_limit = 600;  // below the CSV, above its stderr message
  const Outcome rp = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", replay_csv}, 60);
  g_child_file_size_limit = -1;
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << " (25: SIGXFSZ)";
  EXPECT_EQ(r.code, 4) << r.out << r.err;
  EXPECT_NE(field(r.out, "output_errors"), "0") << r.out;
  EXPECT_NE(field(r.out, "csv_lines_lost"), "0") << r.out;
  const std::string text = slurp(csv);
  EXPECT_LE(text.size(), 16384u);
  EXPECT_TRUE(!text.empty() && text.back() == '\n') << "a cut last line";
  ASSERT_FALSE(rp.hung);
  EXPECT_EQ(rp.signal, 0) << "replay killed by signal " << rp.signal;
  EXPECT_EQ(rp.code, 4) << rp.err;
  EXPECT_NE(rp.err.find("pose lines not written"), std::string::npos) << rp.err;
  // Its whole lines would look like the replay of a shorter recording (found probing: header and
  // 19 rows left): removed, as a stopped replay's CSV is.
  EXPECT_NE(rp.err.find("removed the incomplete file"), std::string::npos) << rp.err;
  EXPECT_FALSE(fs::exists(replay_csv)) << slurp(replay_csv);
  // pattern's PGM cut by the limit was left (found probing: 2048 bytes that look like a pattern).
  g_child_file_size_limit = 1024;
  const Outcome pt = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--out", dir + "/cut.pgm"}, 60);
  g_child_file_size_limit = -1;
  EXPECT_NE(pt.code, 0) << pt.err;
  EXPECT_NE(pt.err.find("removed the cut file"), std::string::npos) << pt.err;
  EXPECT_FALSE(fs::exists(dir + "/cut.pgm")) << "a cut pattern is left";
  // A device named as the output is not a cut file: `pattern --out /dev/full` as root removed the
  // device node itself (found probing; here a private node of the same device).
  if (::mknod((dir + "/full").c_str(), S_IFCHR | 0666, makedev(1, 7)) == 0) {
    const Outcome pd = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--out", dir + "/full"}, 60);
    EXPECT_NE(pd.code, 0) << pd.err;
    EXPECT_NE(pd.err.find("nothing removed (not a regular file)"), std::string::npos) << pd.err;
    EXPECT_TRUE(fs::is_character_file(dir + "/full")) << "the device node was removed";
  }
  // Through a link the file it leads to is the one cut: removing the link left it (found probing).
  const std::string target = dir + "/dated.csv", link = dir + "/latest.csv";
  fs::create_symlink(target, link);
  g_child_file_size_limit = 600;
  const Outcome rl = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", link}, 60);
  g_child_file_size_limit = -1;
  EXPECT_EQ(rl.code, 4) << rl.err;
  EXPECT_NE(rl.err.find("removed the incomplete file " + target), std::string::npos) << rl.err;
  EXPECT_FALSE(fs::exists(target)) << "the cut file behind the link is left: " << slurp(target);
}

// The candump log under the same limit ends in whole lines (found probing, on a full tmpfs: the
// log ended in a torn "(000" while the CSV is cut back to its last whole line). Every line is a
// candump line; the cut bytes are counted in can_log_bytes_lost.
TEST(CliFaults, ACandumpLogCutShortEndsInWholeLines) {
  const std::string dir = work_dir() + "/fsize_can";
  fs::create_directories(dir);
  const std::string log = dir + "/can.log";
  const std::string cfg = small_config(dir, "output: {poses_csv: /dev/null}\ncan: {log_file: " + log + "}\n");
  for (const long limit : {16384L, 20000L, 30011L}) {
    g_child_file_size_limit = limit;
    const Outcome r = run({"run", "--config", cfg, "--duration", "2"}, 60);
    g_child_file_size_limit = -1;
    ASSERT_FALSE(r.hung);
    EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal;
    EXPECT_EQ(r.code, 4) << r.out << r.err;
    EXPECT_NE(field(r.out, "can_log_bytes_lost"), "0") << r.out;
    const std::string text = slurp(log);
    EXPECT_LE(text.size(), static_cast<std::size_t>(limit));
    ASSERT_TRUE(!text.empty() && text.back() == '\n') << "limit " << limit << ": a torn last line: ..." << text.substr(text.size() - std::min<std::size_t>(text.size(), 60));
    std::istringstream lines(text);
    int n = 0;
    for (std::string line; std::getline(lines, line); ++n) {
      ASSERT_TRUE(line.size() > 20 && line[0] == '(' && line.find(") can0 ") != std::string::npos && line.find('#') != std::string::npos)
          << "limit " << limit << ", line " << n << ": " << line;
    }
    EXPECT_GT(n, 100);
  }
}

// view --out on a regular file or below one: refused by the option before any input is read
// (it was a bare "filesystem error: cannot create directories: Not a directory [afile]").
TEST(CliFaults, ViewOutThatIsAFileIsNamedByTheOption) {
  const std::string dir = work_dir() + "/view_out_file";
  fs::create_directories(dir);
  std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,1,2,3,0.5,TRACKING\n";
  std::ofstream(dir + "/afile") << "x\n";
  const Refusal cases[] = {
      {{"view", "--poses", dir + "/poses.csv", "--out", dir + "/afile"},
       "--out: '" + dir + "/afile' cannot hold the pictures: it is a regular file, not a directory"},
      {{"view", "--poses", dir + "/poses.csv", "--out", dir + "/afile/sub"},
       "--out: '" + dir + "/afile/sub' cannot hold the pictures: it is not accessible (Not a directory)"},
  };
  for (const Refusal& c : cases) ASSERT_NO_FATAL_FAILURE(expect_refused(c, 20));
  EXPECT_EQ(slurp(dir + "/afile"), "x\n");
}

// view without gnuplot (found probing): exit 1, and the reason on standard error with the command
// to draw the plot by hand — it was printed on standard output, stderr empty.
TEST(CliFaults, ViewWithoutGnuplotSaysSoOnStandardError) {
  const std::string dir = work_dir() + "/view_no_gnuplot";
  fs::create_directories(dir);
  std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,1,2,3,0.5,TRACKING\n";
  const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
  ::setenv("PATH", (dir + "/no_such_bin").c_str(), 1);
  const Outcome r = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/out"}, 20);
  ::setenv("PATH", path.c_str(), 1);
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_NE(r.err.find("sempose view: plot not drawn: gnuplot not found (apt-get install gnuplot-nox); then run: cd '"),
            std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("not drawn"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(dir + "/out/track.gp")) << "the script to draw it by hand";
}

// A replay config whose modelled compute time makes every replay of a recording the same: with
// the measured one (the default) the time stamps follow the machine's load, and through the
// motion model's velocity the ROIs and the poses' last digits do too (two replays in one CI run
// gave rms_px 0.2464 and 0.2472).
std::string repeatable_replay_config(const std::string& dir) {
  const std::string path = dir + "/repeatable.yaml";
  std::ofstream(path) << "pipeline: {virtual_compute_ns: 200000}\n";
  return path;
}

// A truth angle is compared whatever its turns: φ + 720° read 361° off (fmod of a negative
// difference), 6 false poses (found probing); and modulo the turn the pose declares its target
// to look the same at (the procedural lamella: 180°), as the benchmark counts it.
TEST(CliFaults, ReplayTruthAnglesAreComparedWhateverTheirTurns) {
  const std::string dir = work_dir() + "/truth_turns";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 12, "2000", 10));  // a standing lamella
  const std::string truth = slurp(dir + "/rec/ground_truth.csv");
  std::string base_rms;
  for (const double turn : {0.0, 720.0, -720.0, 540.0, -900.0}) {
    std::istringstream in(truth);
    std::ostringstream turned;
    std::string line;
    std::getline(in, line);
    turned << line << "\n";
    while (std::getline(in, line)) {
      const std::size_t c = line.rfind(',');
      turned << line.substr(0, c + 1) << std::stod(line.substr(c + 1)) + turn << "\n";
    }
    const std::string t = dir + "/t.csv";
    std::ofstream(t) << turned.str();
    const Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--config",
                           repeatable_replay_config(dir), "--truth", t, "--out", dir + "/o.csv"},
                          60);
    ASSERT_EQ(r.code, 0) << r.err;
    ASSERT_NE(field(r.out, "poses_compared"), "0") << r.out;
    if (turn == 0.0) base_rms = field(r.out, "rms_deg");
    EXPECT_EQ(field(r.out, "rms_deg"), base_rms) << "truth turned " << turn << ": " << r.out;
    EXPECT_EQ(field(r.out, "false_tracking"), "0") << "truth turned " << turn << ": " << r.out;
  }
}

// Columns after the target (a hand-made truth with a scale column) were read and dropped without
// a word (noticed last round): replay says they are not compared, and compares the rest as before.
TEST(CliFaults, ReplayTruthColumnsPastTheTargetAreNamedAsNotCompared) {
  const std::string dir = work_dir() + "/truth_wide";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 12, "2000", 10));
  const auto replay = [&](const std::string& truth) {
    return run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--config", repeatable_replay_config(dir),
                "--truth", truth, "--out", dir + "/o.csv"},
               60);
  };
  const Outcome plain = replay(dir + "/rec/ground_truth.csv");
  ASSERT_EQ(plain.code, 0) << plain.err;
  EXPECT_EQ(plain.err.find("are not read"), std::string::npos) << plain.err;
  std::istringstream in(slurp(dir + "/rec/ground_truth.csv"));
  std::ostringstream wide;
  std::string line;
  std::getline(in, line);
  wide << line << (line.find("target") == std::string::npos ? ",target" : "") << ",scale,note\n";
  while (std::getline(in, line)) {
    wide << line << (std::count(line.begin(), line.end(), ',') == 3 ? ",0" : "") << ",1.25,7\n";
  }
  const std::string t = dir + "/wide.csv";
  std::ofstream(t) << wide.str();
  const Outcome r = replay(t);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("only frame,x_px,y_px,phi_deg,target are compared; not read: 'scale' (column 6), 'note' (column 7)"),
            std::string::npos) << r.err;
  EXPECT_EQ(field(r.out, "poses_compared"), field(plain.out, "poses_compared")) << r.out;
  EXPECT_EQ(field(r.out, "rms_px"), field(plain.out, "rms_px")) << r.out;
}

// A --truth of no usable row (empty, a header only — sim's truth for a target never in the
// field —, only non-finite rows) compared nothing and counted nothing: poses_compared=0
// false_tracking=0 tracking_without_truth=0, a clean-looking pass. Now it says so, and every
// TRACKING pose is one without truth.
TEST(CliFaults, ReplayTruthWithoutAUsableRowCountsEveryTrackingPose) {
  const std::string dir = work_dir() + "/empty_truth";
  fs::create_directories(dir);
  // A standing lamella at 2000 ns and a 10-frame pattern: tracked (17 of 20 TRACKING here).
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 20, "2000", 10));
  int n = 0;
  for (const char* text : {"", "frame,x_px,y_px,phi_deg\n", "frame,x_px,y_px,phi_deg\n0,nan,1,2\n1,inf,1,2\n"}) {
    const std::string truth = dir + "/truth" + std::to_string(++n) + ".csv", out = dir + "/o" + std::to_string(n) + ".csv";
    std::ofstream(truth) << text;
    const Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--truth", truth, "--out", out}, 60);
    ASSERT_FALSE(r.hung);
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("--truth '" + truth + "' has no usable row"), std::string::npos) << r.err;
    const std::string poses = slurp(out);
    long tracking = 0;
    for (std::size_t p = poses.find(",TRACKING,"); p != std::string::npos; p = poses.find(",TRACKING,", p + 1)) ++tracking;
    ASSERT_GT(tracking, 0) << "the standing lamella is tracked:\n" << poses;
    EXPECT_EQ(field(r.out, "tracking_without_truth"), std::to_string(tracking)) << r.out;
    EXPECT_EQ(field(r.out, "poses_compared"), "0") << r.out;
  }
  // A truth of a target this replay does not track (found probing: all of target 1 beside one
  // pattern compared nothing, unsaid but for tracking_without_truth).
  const std::string other = dir + "/truth_target1.csv";
  std::ofstream(other) << "frame,x_px,y_px,phi_deg,target\n0,160,120,0,1\n1,160,120,0,1\n";
  const Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--truth", other, "--out", dir + "/o9.csv"}, 60);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("2 of its 2 rows are of a target this replay does not track (it tracks target 0)"), std::string::npos)
      << r.err;
}

// Every signal whose default action ends the process and that comes from outside stops a run
// as SIGTERM does: one `stopped by SIGxxx` line, the summary, a whole CSV whose rows are the
// summary's poses, exit 0. SIGQUIT, SIGALRM and SIGUSR2 (and the rest) used to kill it with
// their default action: no summary, the CAN output not stopped, the candump log unflushed.
TEST(CliFaults, EverySignalThatWouldEndARunStopsItCleanly) {
  const std::string dir = work_dir() + "/signals";
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv", can_log = dir + "/can.log";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + can_log + "}\n");
  struct Sig {
    int sig;
    std::string name;
  };
  std::vector<Sig> sigs = {{SIGQUIT, "SIGQUIT"},     {SIGALRM, "SIGALRM"}, {SIGUSR2, "SIGUSR2"}, {SIGVTALRM, "SIGVTALRM"},
                           {SIGPROF, "SIGPROF"},     {SIGIO, "SIGIO"},     {SIGPWR, "SIGPWR"},   {SIGSTKFLT, "SIGSTKFLT"},
                           {SIGXCPU, "SIGXCPU"},     {SIGRTMIN, "SIGRTMIN"}, {SIGRTMIN + 5, "SIGRTMIN+5"},
                           {SIGRTMAX, "SIGRTMAX"}};
  for (const Sig& s : sigs) {
    fs::remove(csv);
    fs::remove(can_log);
    const Outcome r = run({"run", "--config", cfg, "--duration", "60"}, 30, kWhenRunning, s.sig);
    ASSERT_FALSE(r.hung) << s.name;
    EXPECT_TRUE(r.exited && r.code == 0) << s.name << ": exit " << r.code << " signal " << r.signal << "\n" << r.out << r.err;
    EXPECT_NE(r.out.find("stopped by " + s.name + "\n"), std::string::npos) << s.name << "\n" << r.out;
    const std::string poses = field(r.out, "poses");
    ASSERT_FALSE(poses.empty()) << s.name << ": no summary\n" << r.out;
    const std::string text = slurp(csv);
    ASSERT_TRUE(!text.empty() && text.back() == '\n') << s.name << ": CSV missing or cut mid-line";
    const long rows = static_cast<long>(std::count(text.begin(), text.end(), '\n')) - 1;  // less the header
    EXPECT_EQ(std::to_string(rows), poses) << s.name;
    const std::string log = slurp(can_log);
    EXPECT_TRUE(!log.empty() && log.back() == '\n') << s.name << ": candump log missing or cut";
  }
}

namespace {

// Starts sempose with `args` (stdout to /dev/null, stderr to `err_path`), sends `sig` once
// `wait_for` exists (or after 60 s) and returns its wait status.
int signal_once_written(const std::vector<std::string>& args, const std::string& wait_for, int sig,
                        const std::string& err_path) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    const int e = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(null, 1);
    dup2(e, 2);
    std::vector<char*> argv{const_cast<char*>(SEMPOSE_BIN)};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(SEMPOSE_BIN, argv.data());
    _exit(127);
  }
  const auto t0 = std::chrono::steady_clock::now();
  while (!fs::exists(wait_for) && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  kill(pid, sig);
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

}  // namespace

// `sempose replay` and `sempose sim` stopped by a signal mid-way used to die by it, leaving a
// CSV of whole lines for the frames so far (replay) or a shorter recording (sim) that looked
// like a whole one to the next replay or pattern. Now the output begun is removed and the
// process still ends by the signal (a shell or make sees what it asked for).
TEST(CliFaults, ReplayAndSimStoppedByASignalLeaveNoOutputThatLooksWhole) {
  const std::string dir = work_dir() + "/offline_sig";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "");
  // sim: SIGTERM once the second frame is on disk.
  {
    const std::string rec = dir + "/rec_cut";
    const pid_t pid = fork();
    if (pid == 0) {
      const int null = ::open("/dev/null", O_WRONLY);
      dup2(null, 1);
      dup2(null, 2);
      execl(SEMPOSE_BIN, SEMPOSE_BIN, "sim", "--out", rec.c_str(), "--frames", "100000", "--config", cfg.c_str(),
            static_cast<char*>(nullptr));
      _exit(127);
    }
    const auto t0 = std::chrono::steady_clock::now();
    while (!fs::exists(rec + "/frame_000001.pgm") &&
           std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    kill(pid, SIGTERM);
    int status = 0;
    waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << "sim still ends by the signal: " << status;
    EXPECT_FALSE(fs::exists(rec + "/frames.csv")) << "the cut recording's time stamps are left";
    EXPECT_FALSE(fs::exists(rec + "/frame_000000.pgm")) << "the cut recording's frames are left";
    EXPECT_FALSE(fs::exists(rec)) << "the folder sim made is left";
  }
  // replay: SIGTERM once its CSV is made (setup done, the frames being tracked).
  Outcome made = run({"sim", "--out", dir + "/rec", "--frames", "300", "--dwell", "2000", "--config", cfg}, 300);
  ASSERT_EQ(made.code, 0) << made.err;
  made = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--average", "5", "--out",
              dir + "/p.pgm"},
             60);
  ASSERT_EQ(made.code, 0) << made.err;
  for (int sig : {SIGTERM, SIGINT, SIGALRM}) {
    const std::string out = dir + "/poses.csv", err = dir + "/replay_err.txt";
    // The frames are loaded at setup and tracked in ~0.2 s after the CSV is made: on a loaded
    // machine this process may wake after the replay has finished (exit 0, every pose written:
    // seen once in CI). That is no stop to test: tried again, up to 5 times.
    int status = 0;
    for (int attempt = 0; attempt < 5; ++attempt) {
      fs::remove(out);
      status = signal_once_written({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", out}, out,
                                   sig, err);
      std::size_t lines = 0;
      for (char ch : slurp(out)) lines += ch == '\n';
      if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0 && lines == 301)) break;  // header + 300 poses
    }
    const std::string text = slurp(err);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig)
        << "replay ends by signal " << sig << " (status " << status << ")\n" << text;
    EXPECT_FALSE(fs::exists(out)) << "a cut poses CSV is left behind:\n" << slurp(out);
    EXPECT_NE(text.find("stopped by "), std::string::npos) << text;
    EXPECT_NE(text.find("removed the incomplete " + out), std::string::npos) << text;
  }
}

// `sempose view` stopped by a signal died by it, leaving a track plot and the ROI pictures
// drawn so far: a folder that looks like the whole view of the run. Now the files this call
// wrote are removed (a file that was in the folder before stays) and it ends by the signal.
TEST(CliFaults, ViewStoppedByASignalLeavesNoPicturesThatLookWhole) {
  const std::string dir = work_dir() + "/view_sig";
  fs::remove_all(dir);
  fs::create_directories(dir + "/v");
  const std::string cfg = small_config(dir, "");
  const Outcome made = run({"sim", "--out", dir + "/rec", "--frames", "200", "--config", cfg}, 300);
  ASSERT_EQ(made.code, 0) << made.err;
  // One pose per recorded frame: every frame gets a large picture, so the view takes seconds.
  {
    std::ofstream csv(dir + "/poses.csv");
    csv << "frame,t_ns,x_px,y_px,phi_deg,score,status\n";
    for (int f = 0; f < 200; ++f) csv << f << "," << f * 1000000 << ",160,120,0,0.9,TRACKING\n";
  }
  std::ofstream(dir + "/v/notes.txt") << "the operator's own file\n";
  for (int sig : {SIGTERM, SIGINT}) {
    const std::string err = dir + "/view_err.txt";
    const int status = signal_once_written({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v", "--frames",
                                            dir + "/rec", "--every", "1", "--scale", "8"},
                                           dir + "/v/roi_000001.png", sig, err);
    const std::string text = slurp(err);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig)
        << "view ends by signal " << sig << " (status " << status << ")\n" << text;
    EXPECT_NE(text.find("stopped by "), std::string::npos) << text;
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir + "/v")) left.push_back(e.path().filename().string());
    EXPECT_EQ(left, std::vector<std::string>{"notes.txt"}) << "pictures left after signal " << sig << ":\n" << text;
  }
}

// `sempose view` on a full disk (here a file-size limit): gnuplot exits 0 when its picture
// could not be written whole, and view said "track.png" and exit 0 over a cut PNG; a ROI picture
// that failed ended with exit 2 (bad input's code) and the pictures before it left (found probing,
// hostile round 8). Now a cut file is an error naming it, exit 1, and every file this call wrote
// is removed, the folder too when view made it; a file that was in the folder before stays.
TEST(CliFaults, ViewOnAFullDiskLeavesNoPicturesThatLookWhole) {
  const std::string dir = work_dir() + "/view_full";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Outcome made = run({"sim", "--out", dir + "/rec", "--frames", "20", "--config", small_config(dir, "")}, 300);
  ASSERT_EQ(made.code, 0) << made.err;
  {
    std::ofstream csv(dir + "/poses.csv");
    csv << "frame,t_ns,x_px,y_px,phi_deg,score,status\n";
    for (int f = 0; f < 20; ++f) csv << f << "," << f * 1000000 << ",160,120,0,0.9,TRACKING\n";
  }
  const std::vector<std::string> view = {"view", "--poses", dir + "/poses.csv", "--frames", dir + "/rec", "--every", "1",
                                         "--scale", "8", "--out"};
  // The plot (~57 kB) cut by the limit; its data and script (~1 kB each) are written whole.
  std::vector<std::string> args = view;
  args.push_back(dir + "/new");
  g_child_file_size_limit = 8192;
  const Outcome plot = run(args, 120);
  g_child_file_size_limit = -1;
  EXPECT_EQ(plot.code, 1) << plot.out << plot.err;
  EXPECT_NE(plot.err.find("track.png: gnuplot's picture is cut short"), std::string::npos) << plot.err;
  EXPECT_FALSE(fs::exists(dir + "/new")) << "the folder view made is left";
  // The plot whole, the first ROI picture (~170 kB at --scale 8) cut.
  fs::create_directories(dir + "/v");
  std::ofstream(dir + "/v/notes.txt") << "the operator's own file\n";
  args = view;
  args.push_back(dir + "/v");
  g_child_file_size_limit = 120 * 1024;
  const Outcome roi = run(args, 120);
  g_child_file_size_limit = -1;
  EXPECT_EQ(roi.code, 1) << roi.out << roi.err;
  EXPECT_NE(roi.err.find("roi_000000.png: PNG write failed"), std::string::npos) << roi.err;
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(dir + "/v")) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"notes.txt"}) << roi.err;
}

// Every frame view draws is read before anything is written (found probing: a truncated frame
// 10 ended view with exit 2 after track.* and roi_000000..09.png were written; a frame of another
// size was drawn without a word, where replay refuses such a recording).
TEST(CliFaults, ViewReadsEveryFrameItDrawsBeforeWriting) {
  const std::string dir = work_dir() + "/view_bad_frame";
  fs::remove_all(dir);
  const Outcome made = run({"sim", "--out", dir + "/rec", "--frames", "12", "--config", small_config(work_dir(), "")}, 120);
  ASSERT_EQ(made.code, 0) << made.err;
  {
    std::ofstream csv(dir + "/poses.csv");
    csv << "frame,t_ns,x_px,y_px,phi_deg,score,status\n";
    for (int f = 0; f < 12; ++f) csv << f << "," << f * 1000000 << ",160,120,0,0.9,TRACKING\n";
  }
  const std::string frame = dir + "/rec/frame_000010.pgm", whole = slurp(frame);
  fs::resize_file(frame, whole.size() / 2);
  Outcome r = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v1", "--frames", dir + "/rec", "--every", "1"});
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("frame_000010.pgm: truncated"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/v1")) << "output written before the bad frame was found";
  std::string wider = "P5\n321 240\n255\n" + std::string(321 * 240, '\x40');
  std::ofstream(frame, std::ios::binary | std::ios::trunc) << wider;
  r = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v2", "--frames", dir + "/rec", "--every", "1"});
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("frame_000010.pgm: size 321x240 differs from"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/v2"));
  // Not drawn (every 4th pose: frames 0, 4, 8), the odd frame is not read: the view is drawn.
  r = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v3", "--frames", dir + "/rec", "--every", "4"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/v3/roi_000008.png"));
}

// A control character in an output path (a newline, a tab, an escape, a NUL from a YAML
// escape) was used as it stood: a file name with a newline breaks every line-oriented tool and
// log, and "a\0b" from YAML was cut to "a". Refused naming the key or option and the
// character, before any output is touched.
TEST(CliFaults, ControlCharactersInOutputPathsAreRefusedByName) {
  const std::string dir = work_dir() + "/ctl";
  fs::remove_all(dir);
  fs::create_directories(dir);
  // Config keys, written with YAML escapes.
  struct Case {
    std::string yaml, key, what;
  };
  for (const Case& c : std::vector<Case>{
           {"output: {poses_csv: \"" + dir + "/a\\nb.csv\"}\n", "output.poses_csv", "a newline (\\n), byte 0x0a"},
           {"can: {log_file: \"" + dir + "/c\\tan.log\"}\n", "can.log_file", "a tab (\\t), byte 0x09"},
           {"output: {hist_dir: \"" + dir + "/h\\e\"}\n", "output.hist_dir", "an escape (\\x1b), byte 0x1b"},
           {"output: {poses_csv: \"" + dir + "/n\\0.csv\"}\n", "output.poses_csv", "a NUL byte (\\0), byte 0x00"},
           {"output: {poses_csv: \"" + dir + "/r.csv\\r\"}\n", "output.poses_csv", "a carriage return"},
           // YAML's own next-line escape (yaml-cpp writes it as the single byte 0x85) and a
           // line separator: accepted and used as file names before (found probing).
           {"output: {poses_csv: \"" + dir + "/nel\\N.csv\"}\n", "output.poses_csv", "a byte that is not UTF-8, byte 0x85"},
           {"can: {log_file: \"" + dir + "/ls\\L.log\"}\n", "can.log_file", "U+2028 (a line separator)"},
       }) {
    const std::string cfg = small_config(dir, c.yaml);
    const Outcome r = run({"run", "--config", cfg, "--duration", "1"}, 60);
    ASSERT_FALSE(r.hung) << c.yaml;
    EXPECT_EQ(r.code, 2) << c.yaml << r.out << r.err;
    EXPECT_NE(r.err.find(c.key + ": '"), std::string::npos) << c.yaml << r.err;
    EXPECT_NE(r.err.find(c.what), std::string::npos) << c.yaml << r.err;
  }
  // Command-line outputs.
  const std::string cfg = small_config(dir, "output: {poses_csv: " + dir + "/ok.csv}\n");
  Outcome made = run({"sim", "--out", dir + "/rec", "--frames", "3", "--config", cfg}, 120);
  ASSERT_EQ(made.code, 0) << made.err;
  const std::string nl = dir + "/x\ny";
  for (const Refusal& c : std::vector<Refusal>{
           {{"run", "--config", cfg, "--duration", "1", "--can-log", nl}, "--can-log: '" + dir + "/x\\ny' holds a newline"},
           {{"run", "--config", cfg, "--duration", "1", "--hist-dir", nl}, "--hist-dir: '" + dir + "/x\\ny' holds a newline"},
           {{"sim", "--out", nl, "--frames", "2"}, "sempose sim: --out: '" + dir + "/x\\ny' holds a newline"},
           {{"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "32", "--out", nl + ".pgm"},
            "sempose pattern: --out: '" + dir + "/x\\ny.pgm' holds a newline"},
           {{"replay", "--frames", dir + "/rec", "--pattern", dir + "/rec/frame_000000.pgm", "--out", nl + ".csv"},
            "sempose replay: --out: '" + dir + "/x\\ny.csv' holds a newline"},
           {{"view", "--poses", dir + "/none.csv", "--out", dir + "/v\x01"}, "sempose view: --out: '" + dir + "/v\\x01' holds a control character, byte 0x01"},
           {{"sim", "--out", dir + "/rec\xc2\x85x", "--frames", "2"},
            "sempose sim: --out: '" + dir + "/rec\\u0085x' holds U+0085 (a next-line control (NEL)), bytes 0xc2 0x85"},
           {{"sim", "--out", dir + "/rec\x9b" "31m", "--frames", "2"}, "sempose sim: --out: '" + dir + "/rec\\x9b31m' holds a byte that is not UTF-8"},
       }) {
    expect_refused(c, 60);
  }
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    EXPECT_EQ(name.find_first_of("\n\t\r\x1b\x01\x85\x9b"), std::string::npos) << "made: " << name;
    EXPECT_NE(name, "n") << "a NUL cut the name short";
    EXPECT_FALSE(name == "ok.csv" || name == "sempose_can.log") << "an output was touched: " << name;
  }
}

// `sim.targets: []` (or every target disabled) recorded the background only without a word.
// Still recorded (a replay of it must report LOST: a false-tracking check), but said on stderr.
TEST(CliFaults, SimWithoutATargetSaysSo) {
  const std::string dir = work_dir() + "/no_target";
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* targets : {"[]", "[{texture: {source: lamella}, size: [60, 40], start: [160, 120, 0], enabled: false}]"}) {
    std::ofstream(dir + "/c.yaml") << "scan: {field_w: 320, field_h: 240}\nsim:\n  targets: " << targets << "\n";
    fs::remove_all(dir + "/rec");
    const Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "2", "--config", dir + "/c.yaml"}, 60);
    ASSERT_FALSE(r.hung);
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("warning: no target in sim.targets"), std::string::npos) << targets << "\n" << r.err;
    EXPECT_NE(r.err.find("the recording shows the background only"), std::string::npos) << r.err;
  }
  // One target in the field: no such warning.
  std::ofstream(dir + "/c.yaml") << "scan: {field_w: 320, field_h: 240}\nsim:\n  targets: [{texture: {source: lamella}, "
                                    "size: [60, 40], start: [160, 120, 0]}]\n";
  fs::remove_all(dir + "/rec");
  const Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "2", "--config", dir + "/c.yaml"}, 60);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("no target"), std::string::npos) << r.err;
}

// Two writers on one output file: a second `sempose run` (or a replay) on the CSV or candump
// log a running one writes truncated the first one's lines and then interleaved its own with
// them. Each output is locked (flock) while written: the second is refused naming the file.
TEST(CliFaults, ASecondWriterOnARunningRunsOutputIsRefused) {
  const std::string dir = work_dir() + "/two_writers";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv", log = dir + "/can.log";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + log + "}\n");
  const std::string first_out = dir + "/first.txt";
  const pid_t first = fork();
  if (first == 0) {
    const int o = ::open(first_out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(o, 1);
    dup2(o, 2);
    execl(SEMPOSE_BIN, SEMPOSE_BIN, "run", "--config", cfg.c_str(), "--duration", "120", static_cast<char*>(nullptr));
    _exit(127);
  }
  const auto t0 = std::chrono::steady_clock::now();
  while (slurp(first_out).find("thread ") == std::string::npos &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  // The same CSV (another candump log), then the same candump log (no CSV), then replay --out.
  const std::string cfg_csv = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + dir + "/other.log}\n");
  Outcome r = run({"run", "--config", cfg_csv, "--duration", "1"}, 60);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("output.poses_csv: '" + csv + "' is being written by another process"), std::string::npos) << r.err;
  r = run({"run", "--config", small_config(dir, ""), "--duration", "1", "--can-log", log}, 60);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("--can-log: '" + log + "' is being written by another process"), std::string::npos) << r.err;
  Outcome made = run({"sim", "--out", dir + "/rec", "--frames", "3", "--config", cfg}, 120);
  ASSERT_EQ(made.code, 0) << made.err;
  made = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--average", "1", "--out",
              dir + "/p.pgm"}, 60);
  ASSERT_EQ(made.code, 0) << made.err;
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", csv}, 60);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("--out: '" + csv + "' is being written by another process"), std::string::npos) << r.err;
  kill(first, SIGTERM);
  int status = 0;
  waitpid(first, &status, 0);
  const std::string out = slurp(first_out);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out;
  // The first run's CSV is its own: a header, then one row per pose it reports.
  const std::string text = slurp(csv);
  ASSERT_TRUE(!text.empty() && text.back() == '\n');
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n') - 1, std::stol(field(out, "poses"))) << out;
  EXPECT_EQ(text.find("frame,", 1), std::string::npos) << "a second header in the CSV";
  // The lock goes with the process: the file can be written again.
  r = run({"run", "--config", cfg_csv, "--duration", "0.5"}, 60);
  EXPECT_EQ(r.code, 0) << r.out << r.err;
}

// `sempose sim` on a full disk (here a file-size limit: a frame cannot be written whole) said
// so and exited 1, but left a cut PGM, empty frames.csv / ground_truth.csv and a folder the
// next sim refused as "already holds a recording". Now what it wrote is removed.
TEST(CliFaults, SimOnAFullDiskLeavesNoHalfRecording) {
  const std::string dir = work_dir() + "/sim_full";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "");
  g_child_file_size_limit = 50 * 1024;  // a 320x240 frame (76,815 bytes) is cut, as at a disk's last block
  const Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "5", "--config", cfg}, 120);
  g_child_file_size_limit = -1;
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_NE(r.err.find("removed the incomplete recording"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/rec")) << "a half recording is left";
  const Outcome again = run({"sim", "--out", dir + "/rec", "--frames", "2", "--config", cfg}, 120);
  EXPECT_EQ(again.code, 0) << again.err;
  // The folders above --out that sim made go too (hostile round 8: `a/b` stayed).
  g_child_file_size_limit = 50 * 1024;
  const Outcome deep = run({"sim", "--out", dir + "/a/b/rec", "--frames", "5", "--config", cfg}, 120);
  g_child_file_size_limit = -1;
  EXPECT_EQ(deep.code, 1) << deep.err;
  EXPECT_FALSE(fs::exists(dir + "/a")) << "the folders sim made above --out are left";
}

// An input path or a file's cell quoted in an error reached stderr raw: a terminal escape in
// `replay --frames` or in a poses CSV's cell could retitle or clear the operator's terminal
// (hostile round 8). Every error line is written escaped.
TEST(CliFaults, ErrorsQuoteInputPathsAndCellsEscaped) {
  const std::string dir = work_dir() + "/escaped_errors";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Outcome rp = run({"replay", "--frames", dir + "/zz\x1b]0;PWN\x07", "--pattern", dir + "/x.pgm", "--out", dir + "/r.csv"});
  EXPECT_EQ(rp.code, 2) << rp.err;
  EXPECT_EQ(rp.err.find('\x1b'), std::string::npos) << rp.err;
  EXPECT_NE(rp.err.find("zz\\x1b]0;PWN\\x07"), std::string::npos) << rp.err;
  std::ofstream(dir + "/esc.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,1,1,1,1,1,TRACK\x1b]0;PWN\x07ING\n";
  const Outcome vw = run({"view", "--poses", dir + "/esc.csv", "--out", dir + "/v"});
  EXPECT_EQ(vw.code, 2) << vw.err;
  EXPECT_EQ(vw.err.find('\x1b'), std::string::npos) << vw.err;
  EXPECT_NE(vw.err.find("status 'TRACK\\x1b]0;PWN\\x07ING'"), std::string::npos) << vw.err;
}

// systemd's notify socket gone: every WATCHDOG=1 failed unsaid and the run ended with a clean
// summary, while systemd would stop it after WatchdogSec (hostile round 9). Now the first failure
// is said, and the count at the end.
TEST(CliFaults, WatchdogPingsThatCannotBeSentAreSaid) {
  const std::string dir = work_dir() + "/watchdog_gone";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ::setenv("NOTIFY_SOCKET", (dir + "/no_listener").c_str(), 1);
  ::setenv("WATCHDOG_USEC", "100000", 1);
  const Outcome r = run({"run", "--config", small_config(dir, ""), "--duration", "1"}, 60);
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("READY could not be sent"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("watchdog: WATCHDOG=1 could not be sent to NOTIFY_SOCKET"), std::string::npos) << r.out;
  EXPECT_TRUE(std::regex_search(r.out, std::regex(R"(warning: systemd: (\d+) of \1 watchdog pings could not be sent)"))) << r.out;
}

// check-rt quotes the tree's own text (a kernel release, a governor): a terminal escape there
// reached stdout raw, and a 1 MB version file was one 1 MB line (hostile round 9).
TEST(CliFaults, CheckRtQuotesTheTreesTextEscaped) {
  const std::string dir = work_dir() + "/check_rt_escape";
  fs::remove_all(dir);
  fs::create_directories(dir + "/proc/sys/kernel");
  std::ofstream(dir + "/proc/sys/kernel/osrelease") << "6.1\x1b]0;PWNED\x07\x1b[2J\n";
  std::ofstream(dir + "/proc/sys/kernel/version") << std::string(1 << 20, 'v') << "\n";
  const Outcome r = run({"check-rt", "--root", dir});
  EXPECT_EQ(r.out.find('\x1b'), std::string::npos) << r.out.substr(0, 2000);
  EXPECT_NE(r.out.find("6.1\\x1b]0;PWNED\\x07"), std::string::npos) << r.out.substr(0, 2000);
  std::size_t longest = 0;
  for (std::size_t a = 0, b; a < r.out.size(); a = b + 1) {
    b = r.out.find('\n', a);
    if (b == std::string::npos) b = r.out.size();
    longest = std::max(longest, b - a);
  }
  EXPECT_LE(longest, 1100u);
}

// A run refused after its outputs' folders were made (a GPIO chip that is not there; a CAN
// interface, a lock, the pipeline's memory alike) left those folders behind (hostile round 8:
// `new1/sub` and `newhist/deep`); a folder that held something before stays.
TEST(CliFaults, ARefusedRunLeavesNoFoldersItMade) {
  const std::string dir = work_dir() + "/run_refused_folders";
  fs::remove_all(dir);
  fs::create_directories(dir + "/kept");
  std::ofstream(dir + "/kept/notes.txt") << "the operator's own file\n";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + dir + "/new1/sub/poses.csv, hist_dir: " + dir +
                                                "/newhist/deep}\ncan: {log_file: " + dir + "/kept/new/can.log}\n"
                                                "gpio: {chip: " + dir + "/no_such_chip, pose_valid_line: 1}\n");
  const Outcome r = run({"run", "--config", cfg, "--duration", "0.3"}, 60);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("no_such_chip"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/new1")) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/newhist")) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/kept/new")) << r.err;
  EXPECT_TRUE(fs::exists(dir + "/kept/notes.txt"));
}

// `count` frames of w x h, every sample `value`, recorded into the folder `frames`.
void write_uniform_frames(const std::string& frames, int w, int h, std::uint16_t value, int count) {
  fs::create_directories(frames);
  sempose::hal::Image img;
  img.width = w;
  img.height = h;
  img.pixels.assign(static_cast<std::size_t>(w) * h, value);
  for (int f = 0; f < count; ++f) sempose::hal::write_pgm(frames + "/frame_00000" + std::to_string(f) + ".pgm", img);
}

// Fourth round: well-formed but degenerate input. `pattern` on blank frames wrote a flat
// pattern (exit 0) that run and replay then refuse; a truth file with two rows for one frame
// compared against the last one without a word (a wrong truth appended to the right one gave
// false_tracking=3, the other order 0); a truth naming frames the recording does not hold
// (another recording's) was used without a word; a 512 ROI on a 320x240 recording passed as
// the whole field; view drew poses outside the frames of another recording without a word.
TEST(CliFaults, DegenerateRecordingsPatternsAndTruthsAreNamed) {
  const std::string dir = work_dir() + "/degenerate";
  write_uniform_frames(dir + "/blank", 320, 240, 0, 3);
  Outcome r = run({"pattern", "--frames", dir + "/blank", "--center", "160,120", "--size", "64", "--out", dir + "/flat.pgm"}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("window around (160, 120) in " + dir + "/blank is flat (every sample 0 in the mean of 3 frames)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir + "/flat.pgm")) << "a flat pattern was written";

  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 4));
  const std::string truth = slurp(dir + "/rec/ground_truth.csv");
  ASSERT_NE(truth.find("\n3,"), std::string::npos) << truth;
  std::ofstream(dir + "/twice.csv") << truth << "2,10.0,10.0,0.0\n";
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--truth", dir + "/twice.csv", "--out",
           dir + "/o.csv"},
          60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--truth: " + dir + "/twice.csv:6: a second row for frame 2 target 0 (the first is on line 4)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir + "/o.csv")) << "output made before the truth was refused";
  std::ofstream(dir + "/other.csv") << "frame,x_px,y_px,phi_deg\n0,160,120,0\n1000,160,120,0\n1001,160,120,0\n";
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--truth", dir + "/other.csv", "--out",
           dir + "/o.csv"},
          60);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("2 of its 3 rows name frames the recording does not hold (it has frames 0..3; the first such "
                       "row is frame 1000)"),
            std::string::npos)
      << r.err;
  // A 512 ROI on the recording's 320x240 field is 240x240, above max_roi 128: it was taken for
  // the whole field and replay ended "100 scans in a row failed" after 3 poses.
  std::ofstream(dir + "/roi512.yaml") << "source: replay\nreplay: {frames_dir: " << dir << "/rec}\n"
                                         << "scan: {max_roi_w: 128, max_roi_h: 128}\n"
                                         << "tracker: {pattern_size_px: 64, roi_size_px: 512}\n";
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--config", dir + "/roi512.yaml", "--out",
           dir + "/o512.csv"},
          60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("tracker.roi_size_px: 512 gives a 240x240 ROI"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/o512.csv"));
  // A schedule naming only target 0 with two --pattern: target 1 got no frame, no word; one
  // naming target 1 with one --pattern failed after the CSV was made.
  std::ofstream(dir + "/sched00.yaml") << "pipeline: {schedule: [0, 0]}\n";
  std::ofstream(dir + "/sched01.yaml") << "sim:\n  targets:\n    - {texture: {source: lamella}, size: [60, 40], start: [100, 120, 0]}\n"
                                       << "    - {texture: {source: lamella}, size: [60, 40], start: [220, 120, 0]}\n"
                                       << "pipeline: {schedule: [0, 1]}\n";
  const std::vector<std::vector<std::string>> schedule_cases = {
      {"--config", dir + "/sched00.yaml", "--pattern", dir + "/p.pgm", "--pattern", dir + "/p.pgm"},
      {"--config", dir + "/sched01.yaml", "--pattern", dir + "/p.pgm"}};
  for (const auto& extra : schedule_cases) {
    std::vector<std::string> args = {"replay", "--frames", dir + "/rec", "--out", dir + "/osched.csv"};
    args.insert(args.end(), extra.begin(), extra.end());
    r = run(args, 60);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find(": pipeline.schedule "), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir + "/osched.csv")) << r.err;
  }
  // view of these poses over the blank 320x240 frames is fine; over a 40x30 recording every
  // pose lies outside the frames: said (it drew pictures of nothing without a word).
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/poses.csv"}, 60);
  ASSERT_EQ(r.code, 0) << r.err;
  write_uniform_frames(dir + "/small", 40, 30, 7, 4);
  for (const std::string frames : {"/blank", "/small"}) {
    r = run({"view", "--poses", dir + "/poses.csv", "--frames", dir + frames, "--every", "1", "--out", dir + "/view" + frames},
            60);
    EXPECT_EQ(r.code, 0) << r.err;
    const bool said = r.err.find("lies outside the 40x30 frames of " + dir + "/small: are the poses from this recording?") !=
                      std::string::npos;
    EXPECT_EQ(said, frames == "/small") << frames << ": " << r.err;
  }
}

// A run refused because its poses' CSV is being written by another process must not have
// touched its CAN log (found probing: the log was emptied before the CSV's lock was tried).
// The other writer here is this test, holding the lock a run or replay would take.
TEST(CliFaults, ARunRefusedOnOneOutputLeavesTheOtherUntouched) {
  const std::string dir = work_dir() + "/lock_order";
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv", can_log = dir + "/can.log";
  std::ofstream(can_log) << "OLD\n";
  const int held = ::open(csv.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  ASSERT_GE(held, 0);
  ASSERT_EQ(::flock(held, LOCK_EX | LOCK_NB), 0);
  const Outcome r = run({"run", "--config", small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + can_log + "}\n"),
                         "--duration", "1"});
  ::close(held);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("is being written by another process"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(can_log), "OLD\n") << "the refused run emptied its CAN log";
}

// Started with a standard stream closed (a wrapper's `>&-`), the first file opened took its
// number and the status lines went into it: run's candump log held 10 status lines, replay's CSV
// began with its report (found probing). Now a closed stream is put on /dev/null first.
TEST(CliFaults, AClosedStandardStreamIsNotWrittenIntoAnOutput) {
  const std::string dir = work_dir() + "/closed_stdio";
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 4));
  const std::string csv = dir + "/poses.csv", can_log = dir + "/can.log";
  const auto only = [](const std::string& text, const std::regex& line) {
    std::istringstream in(text);
    std::string l, first_bad;
    int n = 0;
    while (std::getline(in, l)) {
      ++n;
      if (first_bad.empty() && !std::regex_match(l, line)) first_bad = l;
    }
    return n > 0 && first_bad.empty() ? std::string() : "line '" + first_bad + "' of " + std::to_string(n);
  };
  const std::regex candump(R"(\(\d+\.\d{6}\) can0 [0-9A-F]{3}#[0-9A-F]*)"), csv_line(R"((frame,|\d).*)");
  for (const int fd : {1, 2}) {
    g_child_closed_fd = fd;
    const Outcome r = run({"run", "--config", small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + can_log + "}\n"),
                           "--duration", "0.3"});
    const Outcome p = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/r.csv"});
    g_child_closed_fd = -1;
    EXPECT_EQ(r.code, 0) << "fd " << fd << " closed: " << r.err;
    EXPECT_EQ(only(slurp(can_log), candump), "") << "fd " << fd << " closed: the candump log holds other lines";
    EXPECT_EQ(only(slurp(csv), csv_line), "") << "fd " << fd << " closed: the poses CSV holds other lines";
    // Replay's report on a closed stdout is lost, and said (hostile round 10); its CSV is whole.
    EXPECT_EQ(p.code, fd == 1 ? 4 : 0) << "fd " << fd << " closed: " << p.err;
    if (fd == 1) {
      EXPECT_NE(r.err.find("the summary:\nsummary: poses="), std::string::npos) << "run's summary, on stderr: " << r.err;
    }
    EXPECT_EQ(slurp(dir + "/r.csv").rfind("frame,", 0), 0u) << "fd " << fd << " closed: replay's CSV does not begin with its header";
    EXPECT_EQ(only(slurp(dir + "/r.csv"), csv_line), "") << "fd " << fd << " closed: replay's CSV holds other lines";
  }
}

// Standard output as the product (`replay --out -`) or as the report's stream, redirected with
// `>>` or onto one of the command's own inputs, or closed (found probing: `replay --out - >>
// FILE` emptied FILE; `>> REC/frames.csv` replaced the recording's time stamps and `run >>
// CONFIG` grew the config with status lines, each exit 0; with stdout closed every pose line
// went to /dev/null, exit 0). Appended to; refused naming the input; refused as closed.
TEST(CliFaults, StandardOutputAppendedToOntoAnInputOrClosedIsHandled) {
  const std::string dir = work_dir() + "/stdout_targets";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "output: {poses_csv: " + dir + "/p.csv}\ncan: {log_file: " + dir + "/can.log}\n");
  ASSERT_TRUE(record_with_pattern(dir, cfg, 4));
  std::ofstream(dir + "/kept.txt") << "a line that must stay\n";
  g_child_stdout = dir + "/kept.txt";
  g_child_stdout_append = true;
  Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", "-"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(slurp(dir + "/kept.txt").rfind("a line that must stay\nframe,t_ns,", 0), 0u) << slurp(dir + "/kept.txt").substr(0, 200);

  const std::string stamps = slurp(dir + "/rec/frames.csv"), config_text = slurp(cfg);
  g_child_stdout = dir + "/rec/frames.csv";
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", "-"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("standard output is the time stamps of --frames"), std::string::npos) << r.err;
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/r.csv"});
  EXPECT_EQ(r.code, 2) << "the report onto the recording: " << r.err;
  EXPECT_EQ(slurp(dir + "/rec/frames.csv"), stamps);
  g_child_stdout = cfg;
  r = run({"run", "--config", cfg, "--duration", "0.3"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("standard output is the config"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(cfg), config_text);
  g_child_stdout.clear();
  g_child_stdout_append = false;

  g_child_closed_fd = 1;
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", "-"});
  g_child_closed_fd = -1;
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--out '-': standard output is closed"), std::string::npos) << r.err;
}

// `run --hist-dir h > h/latency_hist.txt`: the dump at exit was renamed over the captured status
// lines and summary, exit 0 (found probing). Refused like a CSV on standard output.
TEST(CliFaults, AHistogramFileThatIsStandardOutputIsRefused) {
  const std::string dir = work_dir() + "/hist_stdout";
  fs::create_directories(dir + "/h");
  g_child_stdout = dir + "/h/latency_hist.txt";
  const Outcome r = run({"run", "--config", small_config(dir, ""), "--duration", "0.2", "--hist-dir", dir + "/h"});
  g_child_stdout.clear();
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--hist-dir: the histogram file " + dir + "/h/latency_hist.txt is this process's standard output"),
            std::string::npos) << r.err;
}

// A restart (the packaged unit's Restart=on-failure after a watchdog kill or a crash) emptied the
// candump log and CSV of the run that failed, 2 s later (found probing). output.keep_previous
// keeps the last run's files as NAME.1; a kept copy that would be the other output is refused.
TEST(CliFaults, KeepPreviousKeepsTheLastRunsOutputs) {
  const std::string dir = work_dir() + "/keep_previous";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv", can_log = dir + "/can.log";
  const std::string cfg =
      small_config(dir, "output: {poses_csv: " + csv + ", keep_previous: true}\ncan: {log_file: " + can_log + "}\n");
  Outcome r = run({"run", "--config", cfg, "--duration", "0.3"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(fs::exists(csv + ".1")) << "a first run has nothing to keep";
  const std::string first_csv = slurp(csv), first_log = slurp(can_log);
  ASSERT_FALSE(first_log.empty());
  r = run({"run", "--config", cfg, "--duration", "0.3"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(slurp(csv + ".1"), first_csv);
  EXPECT_EQ(slurp(can_log + ".1"), first_log);
  EXPECT_NE(slurp(can_log), first_log) << "the second run's own log";
  EXPECT_NE(r.out.find("output.keep_previous: the last run's " + can_log + " kept as " + can_log + ".1"), std::string::npos) << r.out;
  // Off (the default): nothing kept beside the outputs.
  fs::remove(csv + ".1");
  r = run({"run", "--config", small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + can_log + "}\n"),
           "--duration", "0.3"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(fs::exists(csv + ".1"));
  r = run({"run", "--config",
           small_config(dir, "output: {poses_csv: " + can_log + ".1, keep_previous: true}\ncan: {log_file: " + can_log + "}\n"),
           "--duration", "0.3"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("can.log_file's kept copy '" + can_log + ".1' (output.keep_previous) is the other output"),
            std::string::npos) << r.err;
}

// Two runs on one histogram folder each said they wrote their histograms there, while one had
// renamed the other's away (found probing). The folder is locked like the files: a run refused on
// it names it, and leaves its CAN log as it was. The other writer here is this test.
TEST(CliFaults, AHistogramFolderAnotherRunWritesIsRefused) {
  const std::string dir = work_dir() + "/hist_lock";
  fs::create_directories(dir + "/h");
  const std::string can_log = dir + "/can.log";
  std::ofstream(can_log) << "OLD\n";
  const int held = ::open((dir + "/h").c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  ASSERT_GE(held, 0);
  ASSERT_EQ(::flock(held, LOCK_EX | LOCK_NB), 0);
  const Outcome r = run({"run", "--config", small_config(dir, "can: {log_file: " + can_log + "}\n"), "--duration", "0.2",
                         "--hist-dir", dir + "/h"});
  ::close(held);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("histograms: '" + dir + "/h' is being written by another process"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(can_log), "OLD\n") << "the refused run emptied its CAN log";
  EXPECT_TRUE(fs::is_empty(dir + "/h"));
  // Free again: the run writes its histograms there.
  const Outcome ok = run({"run", "--config", small_config(dir, "can: {log_file: " + can_log + "}\n"), "--duration", "0.2",
                          "--hist-dir", dir + "/h"});
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_TRUE(fs::exists(dir + "/h/latency_hist.txt"));
}

// Under a thread limit (a unit's TasksMax=, `prlimit --nproc`) the stages' threads failed only
// after the poses CSV and the candump log had been emptied (exit 3, the last run's outputs gone),
// and the learned appearance's worker failed as a bare "Resource temporarily unavailable" (found
// probing). The threads are tried before any output is touched, and both name the limit.
TEST(CliFaults, AThreadLimitIsNamedBeforeAnyOutputIsTouched) {
  const std::string dir = work_dir() + "/nproc";
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv", can_log = dir + "/can.log";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + can_log + "}\n");
  std::string text = slurp(cfg);
  const std::string tracker = "tracker: {pattern_size_px: 64, roi_size_px: 96}";
  ASSERT_NE(text.find(tracker), std::string::npos);
  text.replace(text.find(tracker), tracker.size(), "tracker: {pattern_size_px: 64, roi_size_px: 96, appearance: {enabled: true}}");
  const std::string learning = dir + "/learning.yaml";
  std::ofstream(learning) << text;
  // Root is not held to RLIMIT_NPROC: the run is made as nobody then, in a folder it may write.
  const long uid = ::geteuid() == 0 ? 65534 : -1;
  for (const std::string& c : {cfg, learning}) {
    std::ofstream(can_log) << "OLD LOG\n";
    std::ofstream(csv) << "OLD CSV\n";
    if (uid >= 0) {
      for (const std::string& f : {dir, csv, can_log}) ASSERT_EQ(::chown(f.c_str(), uid, uid), 0) << f;
      fs::permissions(dir, fs::perms::all);
    }
    g_child_process_limit = 1;  // every thread of this user counts: none can be made
    g_child_uid = uid;
    const Outcome r = run({"run", "--config", c, "--duration", "0.2"});
    g_child_process_limit = g_child_uid = -1;
    if (r.code == 126 || r.code == 127) GTEST_SKIP() << "cannot run sempose as nobody here: " << r.err;
    if (r.code == 0) GTEST_SKIP() << "RLIMIT_NPROC is not enforced for this user here";
    EXPECT_EQ(r.code, c == cfg ? 3 : 2) << c << "\n" << r.err;
    EXPECT_NE(r.err.find(c == cfg ? "the pipeline: cannot create its 2 threads" : "the learned appearance's worker thread"),
              std::string::npos) << r.err;
    EXPECT_NE(r.err.find("thread limit (ulimit -u, RLIMIT_NPROC; a systemd unit's TasksMax= or LimitNPROC=)"), std::string::npos)
        << r.err;
    EXPECT_EQ(slurp(can_log), "OLD LOG\n") << c << ": the refused run emptied the CAN log";
    EXPECT_EQ(slurp(csv), "OLD CSV\n") << c << ": the refused run emptied the CSV";
  }
}

// A frame pool larger than the memory left (pipeline.frame_pool_slots of a large field, in range)
// failed only when the pipeline was built, after the outputs were opened: a bare std::bad_alloc,
// and the refused run's CSV header written over the last run's first bytes (found probing). Now
// it is refused with the inputs, naming the key, and the last run's files are left whole.
TEST(CliFaults, AFramePoolBeyondTheMemoryLeftIsRefusedAndTheLastRunsFilesKept) {
  const std::string dir = work_dir() + "/frame_pool";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv", can_log = dir + "/can.log", cfg = dir + "/big.yaml";
  std::ofstream(cfg) << "scan: {field_w: 4096, field_h: 4096, max_roi_w: 128, max_roi_h: 128}\n"
                        "sim:\n  clock: virtual\n  targets:\n    - {texture: {source: lamella}, size: [60, 40], start: [160, 120, 0]}\n"
                        "tracker: {pattern_size_px: 64, roi_size_px: 96}\n"
                        "pipeline: {lock_memory: false, hold_dma_latency: false, frame_pool_slots: 64,\n"
                        "           acquisition: {cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0},\n"
                        "           output: {cpu: -1, priority: 0}, non_rt_cpu: -1}\n"
                        "service: {stall_timeout_ms: 20000}\noutput: {poses_csv: " << csv << "}\ncan: {log_file: " << can_log << "}\n";
  const std::string last_csv = "frame,t_ns,x_px,y_px,phi_deg,score,status,target,scale\n0,1,2,3,4,0.9,TRACKING,1,1.0\n";
  std::ofstream(csv) << last_csv;
  std::ofstream(can_log) << "OLD LOG\n";
  g_child_address_space_limit = 1536L << 20;  // 64 slots of 4096x4096 at 2 B: 2147 MB
  const Outcome r = run({"run", "--config", cfg, "--duration", "0.2"}, 120);
  g_child_address_space_limit = -1;
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("the frame pool needs 2147 MB, more than the"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("64 slots (pipeline.frame_pool_slots) of the 4096x4096 field"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(csv), last_csv) << "the refused run touched the last run's CSV";
  EXPECT_EQ(slurp(can_log), "OLD LOG\n");
}

// The stall rule (service.stall_timeout_ms at least twice a full-field scan) was checked on
// scan.field_w/h only, but a recording sets the field: a 4096² recording passed under the 2 s
// default and every start search was reported as a stall, the heartbeat LOST (found probing).
// Checked again on the source's field, before any output is touched.
TEST(CliFaults, TheStallRuleHoldsForARecordingsField) {
  const std::string dir = work_dir() + "/stall_field";
  fs::remove_all(dir);
  fs::create_directories(dir + "/rec");
  sempose::hal::Image img;
  img.width = img.height = 2048;  // 2048² at 250 ns: 1.05 s a field scan
  img.bits = 8;
  img.pixels.assign(static_cast<std::size_t>(img.width) * img.height, 100);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) img.pixels[static_cast<std::size_t>(1000 + y) * img.width + 1000 + x] = (x / 8 + y / 16) % 2 ? 200 : 20;
  sempose::hal::write_pgm(dir + "/rec/frame_000000.pgm", img);
  sempose::hal::Image pat;
  pat.width = pat.height = 64;
  pat.bits = 8;
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) pat.pixels.push_back((x / 8 + y / 16) % 2 ? 200 : 20);
  sempose::hal::write_pgm(dir + "/p.pgm", pat);
  const std::string csv = dir + "/poses.csv", cfg = dir + "/rec.yaml";
  std::ofstream(cfg) << "source: replay\nreplay: {frames_dir: " << dir << "/rec, clock: real}\n"
                        "targets: [{name: t, pattern_sets: [{file: p.pgm}]}]\n"
                        "tracker: {pattern_size_px: 64, roi_size_px: 96}\n"
                        "pipeline: {lock_memory: false, hold_dma_latency: false,\n"
                        "           acquisition: {cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0},\n"
                        "           output: {cpu: -1, priority: 0}, non_rt_cpu: -1}\n"
                        "output: {poses_csv: " << csv << "}\ncan: {log_file: " << dir << "/can.log}\n";
  std::ofstream(csv) << "OLD CSV\n";
  const Outcome r = run({"run", "--config", cfg, "--duration", "0.5"}, 120);
  ASSERT_FALSE(r.hung);
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("service.stall_timeout_ms: 2000 is below 2"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("(2048x2048 px at 250 ns)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("the field is the source's, not scan.field_w/h"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(csv), "OLD CSV\n");
  // Given room for it, the same recording runs.
  std::ofstream(cfg, std::ios::app) << "service: {stall_timeout_ms: 5000}\n";
  const Outcome ok = run({"run", "--config", cfg, "--duration", "0.5"}, 120);
  EXPECT_EQ(ok.code, 0) << ok.out << ok.err;
}

// `replay --config RUN.yaml` passed over the run's replay.frames_dir (another recording than
// --frames), replay.loop and output.poses_csv without a word (found probing); and a run config
// whose CSV this user cannot write (the service's log folder) refused a replay that never writes
// it. Both said, neither refused.
TEST(CliFaults, ReplaySaysWhatOfARunsConfigItDoesNotUse) {
  const std::string dir = work_dir() + "/replay_run_config";
  fs::remove_all(dir);
  fs::create_directories(dir + "/other");
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 3));
  const std::string cfg = dir + "/run.yaml";
  std::ofstream(cfg) << "source: replay\nreplay: {frames_dir: " << dir << "/other, loop: true}\n"
                        "output: {poses_csv: /proc/sempose-nowhere/poses.csv}\n";
  const Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--config", cfg, "--out", dir + "/o.csv"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("not used by replay: replay.frames_dir '" + dir + "/other' (--frames '" + dir + "/rec' is replayed), "
                       "replay.loop (a replay goes through the frames once), output.poses_csv '/proc/sempose-nowhere/poses.csv' "
                       "(the poses go to --out)"),
            std::string::npos)
      << r.err;
}

// A modelled compute (pipeline.virtual_compute_ns, in range) longer than the longest ROI scan made
// the virtual-time queue grow for the whole run (318 s end-to-end in a 2 s run, dropped=0; found
// probing): said at start, so the latencies are not read as measured. Not said when it fits.
TEST(CliFaults, AVirtualComputeLongerThanAnyScanIsSaid) {
  const std::string dir = work_dir() + "/virtual_compute";
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* compute : {"200000000", "100000"}) {
    const std::string cfg = dir + "/v" + compute + ".yaml";
    std::ofstream(cfg) << small_scene("virtual_compute_ns: " + std::string(compute) + ",") << "can: {log_file: " << dir
                       << "/can.log}\n";
    const Outcome r = run({"run", "--config", cfg, "--duration", "0.3"});
    EXPECT_EQ(r.code, 0) << r.err;
    const bool warned = r.out.find("warning: pipeline.virtual_compute_ns " + std::string(compute) +
                                   " ns is longer than the longest ROI scan") != std::string::npos;
    EXPECT_EQ(warned, std::string(compute) == "200000000") << r.out;
  }
}

// targets[i].start_area through the whole path (config -> trackers -> the start search): inside
// the recording's field the replay tracks; outside it (a recording sets the field, so the config
// cannot check it) it is refused naming the key and the field.
TEST(CliFaults, AStartAreaIsUsedAndCheckedAgainstTheRecordingsField) {
  const std::string dir = work_dir() + "/start_area";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(
      record_with_pattern(dir, small_config(dir, ""), 6));  // the lamella still at (160, 120)
  // The poses' distance from the target, row by row (the CSV's x_px, y_px).
  auto distances = [&] {
    std::vector<double> d;
    std::ifstream in(dir + "/o.csv");
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      double x = 0, y = 0;
      if (std::sscanf(line.c_str(), "%*[^,],%*[^,],%lf,%lf", &x, &y) == 2)
        d.push_back(std::hypot(x - 160, y - 120));
    }
    return d;
  };
  for (const std::string area : {"[160, 120, 40]", "[60, 60, 30]", "[400, 100, 50]"}) {
    const std::string cfg = dir + "/area.yaml";
    std::ofstream(cfg) << "targets: [{name: lam, pattern_sets: [{file: p.pgm}], start_area: "
                       << area
                       << "}]\n"
                          "tracker: {pattern_size_px: 64, roi_size_px: 96}\n";
    fs::remove(dir + "/o.csv");
    const Outcome r =
        run({"replay", "--frames", dir + "/rec", "--config", cfg, "--out", dir + "/o.csv"});
    if (area == "[400, 100, 50]") {
      EXPECT_EQ(r.code, 2) << r.err;
      EXPECT_NE(
          r.err.find(
              "targets[0].start_area: centre (400, 100) is outside the source's 320x240 field"),
          std::string::npos)
          << r.err;
      continue;
    }
    EXPECT_EQ(r.code, 0) << r.err;
    const std::vector<double> d = distances();
    ASSERT_EQ(d.size(), 6u) << area;
    for (const double dist : d) {
      if (area == "[160, 120, 40]")
        EXPECT_LT(dist, 3.0) << area << ": the target is in the area";
      else
        EXPECT_GT(dist, 40.0) << area << ": the searches keep to the area, where the target is not";
    }
  }
}

// A reader's shared lock (a backup or log shipper copying the CAN log under `flock -s`) was
// reported as another sempose writing it (found probing). The holder and the lock's kind are
// named from /proc/locks; the writer's message names the process too.
TEST(CliFaults, TheProcessHoldingAnOutputsLockIsNamed) {
  const std::string dir = work_dir() + "/lock_holder";
  fs::create_directories(dir);
  const std::string can_log = dir + "/can.log";
  std::ofstream(can_log) << "OLD\n";
  const std::string me = "process " + std::to_string(::getpid());
  for (const int kind : {LOCK_SH, LOCK_EX}) {
    const int held = ::open(can_log.c_str(), O_RDONLY | O_CLOEXEC);
    ASSERT_GE(held, 0);
    ASSERT_EQ(::flock(held, kind | LOCK_NB), 0);
    const Outcome r = run({"run", "--config", small_config(dir, "can: {log_file: " + can_log + "}\n"), "--duration", "0.2"});
    ::close(held);
    EXPECT_EQ(r.code, 2) << r.err;
    const std::string said = kind == LOCK_SH ? "can.log_file: '" + can_log + "' is locked by " + me + " with a reader's shared lock"
                                             : "can.log_file: '" + can_log + "' is being written by another process (" + me +
                                                   " holds a lock on it";
    EXPECT_NE(r.err.find(said), std::string::npos) << r.err;
    EXPECT_EQ(slurp(can_log), "OLD\n");
  }
}

// Every output opened before any is emptied (found probing: under `ulimit -n 6` a run whose CSV
// could not be opened, "Too many open files", had already emptied the last run's CAN log). For
// each limit on open files that refuses the run: the last run's outputs are as they were, and
// a first run's (none there before) are not left behind empty.
TEST(CliFaults, ARunRefusedForWantOfFilesEmptiesNoOutput) {
  const std::string dir = work_dir() + "/nofile";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string csv = dir + "/poses.csv", can_log = dir + "/can.log";
  const std::string cfg = small_config(dir, "output: {poses_csv: " + csv + "}\ncan: {log_file: " + can_log + "}\n");
  int refused_at_the_csv = 0;
  bool ran = false;  // a limit the run needs no more than: higher ones run too
  for (long limit = 4; limit <= 32 && !ran; ++limit) {
    for (const bool had_outputs : {true, false}) {
      fs::remove(csv);
      fs::remove(can_log);
      if (had_outputs) {
        std::ofstream(can_log) << "OLD LOG\n";
        std::ofstream(csv) << "OLD CSV\n";
      }
      g_child_open_files_limit = limit;
      const Outcome r = run({"run", "--config", cfg, "--duration", "0.2"});
      g_child_open_files_limit = -1;
      ASSERT_FALSE(r.hung) << limit;
      ASSERT_TRUE(r.exited) << "limit " << limit << ": signal " << r.signal << "\n" << r.err;
      if (r.code == 0) {
        ran = true;
        continue;
      }
      refused_at_the_csv += r.err.find("output.poses_csv: cannot create") != std::string::npos;
      if (had_outputs) {
        EXPECT_EQ(slurp(can_log), "OLD LOG\n") << "limit " << limit << ": the refused run emptied the CAN log\n" << r.err;
        EXPECT_EQ(slurp(csv), "OLD CSV\n") << "limit " << limit << ": the refused run emptied the CSV\n" << r.err;
      } else {
        EXPECT_FALSE(fs::exists(can_log)) << "limit " << limit << ": a refused first run left its CAN log\n" << r.err;
        EXPECT_FALSE(fs::exists(csv)) << "limit " << limit << ": a refused first run left its CSV\n" << r.err;
      }
    }
  }
  EXPECT_GT(refused_at_the_csv, 0) << "no limit refused the run at the CSV, the case this test is for";
  EXPECT_TRUE(ran) << "no limit up to 32 open files ran";
}

// Outputs are judged where writing them lands, through links (found probing: a symbolic link
// to a frame as `pattern --out` overwrote the frame, a hard link too; `replay --out LINK` with
// LINK → REC/new.pgm put a PGM among the frames; `view --out REC` wrote its pictures into the
// recording; a CAN log and a poses' CSV that were one file through a link were not seen as one).
TEST(CliFaults, OutputsThroughLinksAreJudgedWhereTheyLand) {
  const std::string dir = work_dir() + "/links";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 2));
  const std::string frame = dir + "/rec/frame_000001.pgm";
  const std::string before = slurp(frame);
  fs::create_symlink(frame, dir + "/soft.pgm");
  fs::create_hard_link(frame, dir + "/hard.pgm");
  for (const char* out : {"/soft.pgm", "/hard.pgm"}) {
    const Outcome r = run({"pattern", "--frames", dir + "/rec", "--center", "160,120", "--size", "64", "--out", dir + out}, 60);
    EXPECT_EQ(r.code, 2) << out << ": " << r.err;
    EXPECT_NE(r.err.find("frame"), std::string::npos) << r.err;
  }
  EXPECT_EQ(slurp(frame), before) << "a frame of the recording was overwritten through a link";
  fs::create_symlink(dir + "/rec/new.pgm", dir + "/poses.csv");  // dangling: writing creates REC/new.pgm
  Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/poses.csv"}, 120);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/rec/new.pgm")) << "replay wrote a PGM into the frames folder";
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/ok.csv"}, 120);
  ASSERT_EQ(r.code, 0) << r.err;
  fs::create_directory_symlink(dir + "/rec", dir + "/pictures");
  for (const char* out : {"/rec", "/pictures"}) {
    r = run({"view", "--poses", dir + "/ok.csv", "--frames", dir + "/rec", "--out", dir + out}, 120);
    EXPECT_EQ(r.code, 2) << out << ": " << r.err;
    EXPECT_NE(r.err.find("is the frames folder"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir + "/rec/track.png"));
  fs::create_symlink(dir + "/one.log", dir + "/also.csv");  // dangling: both outputs are one.log
  r = run({"run", "--config", small_config(dir, "output: {poses_csv: " + dir + "/also.csv}\ncan: {log_file: " + dir + "/one.log}\n"),
           "--duration", "1"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("is also output.poses_csv"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/one.log")) << "a refused run created its output";
}

// `sim --dwell` off the scan generator's dwell steps recorded frames "at" a dwell no scan had
// (found probing: --dwell 123 with 50 ns steps). Refused, naming the step and what it would be.
TEST(CliFaults, SimDwellOffTheStepsIsRefused) {
  const std::string dir = work_dir() + "/dwell_step";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Outcome r = run({"sim", "--out", dir + "/rec", "--frames", "2", "--dwell", "123", "--config", small_config(dir, "")}, 60);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--dwell: 123 ns is not a multiple of scan.dwell_step_ns"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/rec"));
}

// An input this user may not read said only "cannot open" when the file existed (its stat
// passed): frames.csv, the truth, a pattern, view's poses. Each now says why. Root reads
// everything, so as root the commands run as nobody.
TEST(CliFaults, AnUnreadableInputSaysWhy) {
  const std::string dir = work_dir() + "/unreadable";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 3));
  Outcome r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/poses.csv"}, 60);
  ASSERT_EQ(r.code, 0) << r.err;
  const long uid = ::geteuid() == 0 ? 65534 : -1;
  if (uid >= 0) {
    for (const auto& e : fs::recursive_directory_iterator(dir)) ASSERT_EQ(::chown(e.path().c_str(), uid, uid), 0) << e.path();
    ASSERT_EQ(::chown(dir.c_str(), uid, uid), 0);
  }
  struct Case {
    std::string file;
    std::vector<std::string> args;
  };
  const std::vector<Case> cases = {
      {dir + "/rec/frames.csv", {"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/o1.csv"}},
      {dir + "/rec/ground_truth.csv",
       {"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--truth", dir + "/rec/ground_truth.csv", "--out",
        dir + "/o2.csv"}},
      {dir + "/p.pgm", {"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/o3.csv"}},
      {dir + "/poses.csv", {"view", "--poses", dir + "/poses.csv", "--out", dir + "/view"}}};
  // Control: the first command as that user with every file readable. It fails only when the
  // user cannot reach the binary or the folder (a TEST_TMPDIR or build tree under a 0700 home),
  // which is this machine's layout, not what the test asks.
  g_child_uid = uid;
  r = run(cases[0].args, 60);
  g_child_uid = -1;
  if (r.code != 0) GTEST_SKIP() << "sempose cannot run as nobody on " << dir << " here: " << r.err;
  for (const Case& c : cases) {
    fs::permissions(c.file, fs::perms::none);
    g_child_uid = uid;
    r = run(c.args, 60);
    g_child_uid = -1;
    fs::permissions(c.file, fs::perms::owner_read | fs::perms::owner_write);
    EXPECT_NE(r.code, 0) << c.file;
    EXPECT_NE(r.err.find(c.file + ": cannot open (Permission denied)"), std::string::npos) << c.file << "\n" << r.err;
  }
  // The recording's folder itself: the library's "filesystem error: directory iterator cannot
  // open directory" came out as it was (found probing).
  fs::permissions(dir + "/rec", fs::perms::none);
  g_child_uid = uid;
  r = run({"replay", "--frames", dir + "/rec", "--pattern", dir + "/p.pgm", "--out", dir + "/o4.csv"}, 60);
  g_child_uid = -1;
  fs::permissions(dir + "/rec", fs::perms::owner_all);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find(dir + "/rec: the recording's folder cannot be read: Permission denied"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/o4.csv"));
}

// SIGUSR1 writes the histograms while running and says so on a status line; a dump that failed
// said "write error" whatever the cause (the reason was on standard error only). The line names
// it now.
TEST(CliFaults, ASigusr1DumpSaysWhereOrWhyNot) {
  const std::string dir = work_dir() + "/usr1";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string cfg = small_config(work_dir(), "output: {poses_csv: /dev/null}\ncan: {log_file: /dev/null}\n");
  Outcome r = run({"run", "--config", cfg, "--duration", "2", "--hist-dir", dir}, 60, kWhenRunning, SIGUSR1);
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("histograms written to " + dir + "\n"), std::string::npos) << r.out;
  g_child_file_size_limit = 3000;
  r = run({"run", "--config", cfg, "--duration", "2", "--hist-dir", dir}, 60, kWhenRunning, SIGUSR1);
  g_child_file_size_limit = -1;
  EXPECT_EQ(r.code, 4) << r.out << r.err;
  EXPECT_NE(r.out.find("histograms NOT written to " + dir + " (File too large)\n"), std::string::npos) << r.out;
}

// Hostile round 10: what is lost on standard output is said and exit 4 for every command's
// --help (only the top-level one did; each command's --help into /dev/full said exit 0), and a
// stdout closed at start (`>&-`, put on /dev/null by main) loses --version, --help and view's
// report as surely (exit 0 before, nothing said); run repeats its summary on stderr then.
TEST(CliFaults, HelpVersionAndReportsLostOnStandardOutputExit4) {
  const std::string dir = work_dir() + "/lost_help";
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* command : {"run", "sim", "pattern", "replay", "check-rt", "view"}) {
    g_child_stdout = "/dev/full";
    const Outcome full = run({command, "--help"});
    g_child_stdout.clear();
    EXPECT_EQ(full.code, 4) << command << " --help into /dev/full: " << full.err;
    EXPECT_NE(full.err.find(std::string("sempose ") + command + ": standard output: the report could not be written"),
              std::string::npos) << full.err;
    g_child_closed_fd = 1;
    const Outcome closed = run({command, "--help"});
    g_child_closed_fd = -1;
    EXPECT_EQ(closed.code, 4) << command << " --help with stdout closed: " << closed.err;
  }
  g_child_closed_fd = 1;
  const Outcome version = run({"--version"});
  g_child_closed_fd = -1;
  EXPECT_EQ(version.code, 4) << version.err;
  EXPECT_NE(version.err.find("sempose --version: standard output was closed when sempose started"), std::string::npos)
      << version.err;
  std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,1,2,3,0.5,TRACKING\n";
  g_child_closed_fd = 1;
  const Outcome view = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v"});
  g_child_closed_fd = -1;
  EXPECT_EQ(view.code, 4) << view.err;
  EXPECT_NE(view.err.find("sempose view: standard output was closed when sempose started"), std::string::npos) << view.err;
}

// Hostile round 10: `view --out vv > vv/track.png` wrote the report into the picture and said
// exit 0 (run and pattern refuse their own outputs as stdout by name).
TEST(CliFaults, ViewRefusesItsReportOntoAFileItWrites) {
  const std::string dir = work_dir() + "/view_onto_own";
  fs::remove_all(dir);
  fs::create_directories(dir + "/v");
  std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,1,2,3,0.5,TRACKING\n";
  for (const char* name : {"track.png", "track.dat", "roi_000003.png"}) {
    g_child_stdout = dir + "/v/" + name;
    const Outcome r = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v"});
    g_child_stdout.clear();
    EXPECT_EQ(r.code, 2) << name << ": " << r.err;
    EXPECT_NE(r.err.find("this process's standard output is " + dir + "/v/" + name + ", a file view writes"), std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(dir + "/v/track.gp")) << name << ": view wrote before refusing";
    fs::remove(dir + "/v/" + name);
  }
  // A file of its own in --out is no picture view writes: the report may go there.
  g_child_stdout = dir + "/v/report.txt";
  const Outcome ok = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v"});
  g_child_stdout.clear();
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_NE(slurp(dir + "/v/report.txt").find("view: 1 poses"), std::string::npos);
}

// Hostile round 10: view's plot depended on the user's ~/.gnuplot (`set datafile separator ","`
// failed it unexplained, `set datafile missing "0"` dropped the not-TRACKING marks with exit 0,
// `pause 3600` hung it); a gnuplot that failed left a blank or empty track.png; one that started
// and failed (exit 127: its libraries not loaded under `ulimit -v`) was called "not found".
TEST(CliFaults, ViewsPlotIsGnuplotsDefaultsBoundedAndNeverLeftHalfDrawn) {
  const std::string dir = work_dir() + "/view_gnuplot";
  fs::remove_all(dir);
  fs::create_directories(dir + "/home");
  std::ofstream(dir + "/poses.csv") << "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,1,2,3,0.5,TRACKING\n"
                                       "1,1000000,2,3,4,0.4,LOST\n";
  std::ofstream(dir + "/home/.gnuplot") << "set datafile separator \",\"\npause 3600\n";
  const std::string home = std::getenv("HOME") ? std::getenv("HOME") : "";
  ::setenv("HOME", (dir + "/home").c_str(), 1);
  const Outcome init = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v1"}, 60);
  ::setenv("HOME", home.c_str(), 1);
  EXPECT_FALSE(init.hung);
  EXPECT_EQ(init.code, 0) << init.err;
  EXPECT_GT(fs::exists(dir + "/v1/track.png") ? fs::file_size(dir + "/v1/track.png") : 0, 10000u) << init.err;
  // Stand-ins for a gnuplot that breaks (the thing under test is view's handling of it).
  const std::string bin = dir + "/bin";
  fs::create_directories(bin);
  const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
  struct Case {
    const char* script;
    const char* expect;
  };
  for (const Case& c : {Case{"printf 'not a png' > track.png; exit 3", "gnuplot failed on " },
                        Case{"exit 127", "(exit status 127)"},
                        Case{"printf 'x' > track.png; exec sleep 60", "gnuplot did not finish within 20 s and was stopped"}}) {
    std::ofstream(bin + "/gnuplot") << "#!/bin/sh\n" << c.script << "\n";
    fs::permissions(bin + "/gnuplot", fs::perms::owner_all);
    ::setenv("PATH", (bin + ":" + path).c_str(), 1);
    const Outcome r = run({"view", "--poses", dir + "/poses.csv", "--out", dir + "/v2"}, 60);
    ::setenv("PATH", path.c_str(), 1);
    EXPECT_FALSE(r.hung) << c.script;
    EXPECT_EQ(r.code, 1) << c.script << ": " << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.script << ": " << r.err;
    EXPECT_EQ(r.err.find("not found"), std::string::npos) << c.script << ": " << r.err;
    EXPECT_FALSE(fs::exists(dir + "/v2/track.png")) << c.script << ": a picture gnuplot did not finish is left";
    EXPECT_TRUE(fs::exists(dir + "/v2/track.gp")) << "the script to draw it by hand";
  }
}

// Hostile round 10: under an address-space limit just below a run's need, memory ran out while
// the outputs were being opened: "out of memory" from main, exit 2, and the 0-byte CSV and
// candump log it had created left in the folder it had made. Swept over limits (where the
// need lies depends on the machine): every refusal names memory and leaves nothing. And sim
// printed a bare "std::bad_alloc" for a field too large for the limit.
TEST(CliFaults, MemoryRunningOutIsNamedAndLeavesNoOutputs) {
  const std::string dir = work_dir() + "/oom_outputs";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string cfg = small_config(dir, "output: {poses_csv: " + dir + "/out/poses.csv}\ncan: {log_file: " + dir + "/out/can.log}\n");
  int refused = 0;
  for (long mib = 8; mib <= 80; mib += 2) {
    g_child_address_space_limit = mib << 20;
    const Outcome r = run({"run", "--config", cfg, "--duration", "0.2"}, 60);
    g_child_address_space_limit = -1;
    ASSERT_FALSE(r.hung) << mib << " MiB";
    // Too little to load the program at all: the loader's refusal, not sempose's.
    if (r.code == 0 || r.err.find("error while loading shared libraries") != std::string::npos) continue;
    ++refused;
    EXPECT_EQ(r.code, 2) << mib << " MiB: " << r.err;
    EXPECT_TRUE(r.err.find("out of memory") != std::string::npos || r.err.find("more than") != std::string::npos)
        << mib << " MiB: " << r.err;
    EXPECT_FALSE(fs::exists(dir + "/out")) << mib << " MiB: a refused run left its outputs: " << r.err;
    fs::remove_all(dir + "/out");
  }
  EXPECT_GT(refused, 0) << "no limit refused the run: the sweep tests nothing";
  std::ofstream(dir + "/big.yaml") << "scan: {field_w: 4096, field_h: 4096, bits: 16}\nsim: {clock: virtual, seed: 1}\n";
  g_child_address_space_limit = 120L << 20;
  const Outcome sim = run({"sim", "--config", dir + "/big.yaml", "--out", dir + "/big", "--frames", "2"}, 60);
  g_child_address_space_limit = -1;
  EXPECT_EQ(sim.code, 2) << sim.err;
  EXPECT_NE(sim.err.find("out of memory (the machine's, or an address-space limit: ulimit -v, RLIMIT_AS)"), std::string::npos)
      << sim.err;
  EXPECT_EQ(sim.err.find("bad_alloc"), std::string::npos) << sim.err;
}

// Hostile round 11: the candump log's ring was emptied once a status period, and its lines that
// did not fit were counted only as can_dropped (a busy bus's counter): with the default 1 MiB
// ring and stats_period_ms 60000, 6468 of 9650 poses reached the log; with log_buffer_bytes
// 4096, 25 of 616; both exit 0, output_errors=0, can_log_bytes_lost=0. The rings are emptied on
// every wake of the main loop now, and a line the ring still cannot hold is lost output: a fault
// line, can_log_bytes_lost, exit 4, as the CSV's ring-full poses are.
TEST(CliFaults, CandumpLogLinesThatDoNotFitItsRingAreLostOutput) {
  const std::string dir = work_dir() + "/can_ring";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const auto config = [&](const std::string& name, const std::string& stats_ms, const std::string& can_extra) {
    const std::string path = dir + "/" + name + ".yaml";
    std::ofstream(path) << small_scene("stats_period_ms: " + stats_ms + ",")
                        << "output: {poses_csv: " << dir << "/" << name << ".csv, print_status: false}\n"
                           "can: {log_file: " << dir << "/" << name << ".log, fd: \"on\"" << can_extra << "}\n";
    return path;
  };
  const auto lines = [](const std::string& text, const std::string& part) {
    std::istringstream in(text);
    std::size_t n = 0;
    for (std::string l; std::getline(in, l);) n += l.find(part) != std::string::npos;
    return n;
  };
  // A long status period with the default ring: every pose's FD frame is in the log.
  const Outcome slow = run({"run", "--config", config("slow", "60000", ""), "--duration", "3"}, 120);
  EXPECT_EQ(slow.code, 0) << slow.out << slow.err;
  EXPECT_EQ(field(slow.out, "can_log_bytes_lost"), "0") << slow.out;
  const std::size_t poses = lines(slurp(dir + "/slow.csv"), ",") - 1;
  EXPECT_GT(poses, 500u);
  EXPECT_EQ(lines(slurp(dir + "/slow.log"), "##"), poses) << "pose frames in the log against the CSV's rows";
  // A ring too small for 50 ms of lines (~1300 poses/s here: ~22 lines fit): a log that lacks
  // poses the CSV has is said, counted, exit 4; one that has them all (a machine too slow to
  // overflow it) is exit 0. Never a log short of lines with exit 0.
  const Outcome tight = run({"run", "--config", config("tight", "100", ", log_buffer_bytes: 4096"), "--duration", "1"}, 120);
  const std::size_t tight_poses = lines(slurp(dir + "/tight.csv"), ",") - 1, logged = lines(slurp(dir + "/tight.log"), "##");
  if (logged < tight_poses) {
    EXPECT_EQ(tight.code, 4) << logged << " of " << tight_poses << " poses logged: " << tight.out << tight.err;
    EXPECT_NE(tight.out.find("fault: an output's ring overflowed between flushes"), std::string::npos) << tight.out;
    EXPECT_NE(field(tight.out, "can_log_bytes_lost"), "0") << tight.out;
  } else {
    EXPECT_EQ(tight.code, 0) << tight.out << tight.err;
    std::printf("note: the 4 KiB candump ring did not overflow on this machine (%zu poses)\n", tight_poses);
  }
}

// Hostile round 11: nm_per_px 1e6 put every pose at 134217727 nm on the wire (POSE_XY's
// saturated ±134 mm), TRACKING; a pattern set without nm_per_px sent pixels labelled nm, in
// whole pixels, without a word. The first is refused at setup with the largest nm/px the field
// allows; the second is said.
TEST(CliFaults, RunRefusesAScaleCanCannotCarryAndSaysAPixelScale) {
  const std::string dir = work_dir() + "/nm_per_px";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_TRUE(record_with_pattern(dir, small_config(dir, ""), 3));
  const auto config = [&](const std::string& set) {
    const std::string path = dir + "/run" + std::to_string(set.size()) + ".yaml";
    std::ofstream(path) << "source: replay\nreplay: {frames_dir: " << dir << "/rec}\ntargets: [{name: a, pattern_sets: [{file: "
                        << dir << "/p.pgm" << set << "}]}]\noutput: {poses_csv: " << dir << "/poses.csv}\ncan: {log_file: "
                        << dir << "/can.log}\npipeline: {lock_memory: false, hold_dma_latency: false, acquisition: "
                           "{cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0}, output: {cpu: -1, "
                           "priority: 0}, non_rt_cpu: -1}\n";
    return path;
  };
  const Outcome far = run({"run", "--config", config(", nm_per_px: 1000000"), "--duration", "1"}, 60);
  EXPECT_EQ(far.code, 2) << far.out << far.err;
  EXPECT_NE(far.err.find("pattern_sets[0].nm_per_px: 1e+06 nm/px puts the 320x240 field's far edge at 320000000 nm, beyond "
                         "the 134217727 nm POSE_XY carries (28 bits of 1 nm): at most 419430 nm/px for this field"),
            std::string::npos) << far.err;
  EXPECT_FALSE(fs::exists(dir + "/poses.csv"));
  const Outcome pixels = run({"run", "--config", config(""), "--duration", "1"}, 60);
  EXPECT_EQ(pixels.code, 0) << pixels.err;
  EXPECT_NE(pixels.out.find("note: targets[0].pattern_sets[0].nm_per_px not given: 1 nm per pixel"), std::string::npos)
      << pixels.out;
  const Outcome told = run({"run", "--config", config(", nm_per_px: 40"), "--duration", "1"}, 60);
  EXPECT_EQ(told.code, 0) << told.err;
  EXPECT_EQ(told.out.find("nm_per_px not given"), std::string::npos) << told.out;
}
