// `sempose run`: the controller. Loads and validates the config (exit 2 on errors), builds
// the scan source, trackers, sinks and pipeline, locks memory, holds /dev/cpu_dma_latency,
// runs the RT stages until SIGINT/SIGTERM/SIGHUP or --duration, drains, dumps histograms and prints
// a summary whose LAST line is machine-readable. SIGUSR1 dumps histograms while running.
//
// Signals are blocked in every thread (the mask is inherited by the RT threads) and taken
// with sigtimedwait on this non-RT thread, so no handler ever runs on an RT thread.
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/stat.h>

#include <algorithm>
#include <iterator>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "cli.hpp"
#include "cli_signals.hpp"
#include "cli_options.hpp"
#include "sempose/session/detector_report.hpp"
#include "sempose/session/nonblocking_stdio.hpp"
#include "sempose/session/run_setup.hpp"
#include "sempose/session/run_summary.hpp"
#include "sempose/config/app_config.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/hal/comedi_scan_source.hpp"
#include "sempose/hal/replay_source.hpp"
#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pipeline/stall_watchdog.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"
#include "sempose/rt/latency_histogram.hpp"
#include "sempose/rt/memory_lock.hpp"
#include "sempose/rt/rt_thread.hpp"
#include "sempose/rt/thread_room.hpp"
#include "sempose/service/pipeline_watchdog.hpp"
#include "sempose/service/systemd_notify.hpp"

namespace {

using namespace sempose;

constexpr double kMaxDurationS = 10 * 365.25 * 86400;

struct Options {
  std::string config;
  double duration_s = 0;  // 0: until a signal
  bool strict_rt = false;
  std::string hist_dir;
  std::string can_log;
};

int usage(std::FILE* out) {
  std::fprintf(out,
               "usage: sempose run --config FILE [--duration S] [--strict-rt] [--hist-dir DIR] [--can-log FILE]\n"
               "  --config FILE    application config (YAML; see config/default.yaml)\n"
               "  --duration S     stop after S seconds (default: run until SIGINT/SIGTERM/SIGHUP)\n"
               "  --strict-rt      refuse to start without SCHED_FIFO, affinity and locked memory\n"
               "  --hist-dir DIR   write latency histograms (cyclictest layout + JSON) to DIR at exit and on SIGUSR1\n"
               "  --can-log FILE   send the CAN frames to a candump log FILE instead of the configured bus\n");
  return out == stdout ? 0 : 2;
}

// The histogram files' names in the histogram folder.
constexpr const char* kHistogramTxt = "latency_hist.txt";
constexpr const char* kHistogramJson = "latency_hist.json";

// nullptr when both files are written in full, else why not (errno's text, or out of memory). A
// full disk shows only when the buffer is flushed, so both files are closed before they are
// judged. Each is written beside its name and renamed over it only when both are whole: found probing on a 64 KiB tmpfs, the run said
// "NOT written" but left latency_hist.txt cut mid-line without its Total/Max trailer (the tail
// a latency check reads) and latency_hist.json empty. A failed dump leaves the last whole one.
// `series` is the run's snapshots, made at setup and refreshed here without allocating; the
// writing itself allocates (streams, formatting), and out of memory there is a failed dump, not
// the end of the run's report (found probing under `ulimit -v`).
const char* dump_histograms(const std::string& dir, const pipeline::Pipeline& p,
                            std::vector<rt::HistogramSnapshot>& series) {
  if (dir.empty()) return nullptr;
  p.histograms().snapshot_into(series);
  std::string txt_part, json_part;
  const char* why = "write error";
  // errno of the step that failed, read before anything else can change it.
  const auto failed = [&why] { why = errno != 0 ? std::strerror(errno) : "write error"; };
  try {
    const std::string txt_path = dir + "/" + kHistogramTxt, json_path = dir + "/" + kHistogramJson;
    txt_part = txt_path + ".part";
    json_part = json_path + ".part";
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    errno = 0;
    std::ofstream txt(txt_part);
    rt::write_cyclictest_histogram(txt, series);
    txt.close();
    if (!txt) {
      failed();
    } else {
      errno = 0;
      std::ofstream json(json_part);
      rt::write_histogram_json(json, series);
      json.close();
      if (!json) {
        failed();
      } else if (std::rename(txt_part.c_str(), txt_path.c_str()) != 0 ||
                 std::rename(json_part.c_str(), json_path.c_str()) != 0) {
        failed();
      } else {
        return nullptr;
      }
    }
  } catch (const std::bad_alloc&) {
    why = "out of memory (an address-space limit: ulimit -v, RLIMIT_AS)";
  }
  if (!txt_part.empty()) std::remove(txt_part.c_str());
  if (!json_part.empty()) std::remove(json_part.c_str());
  std::fprintf(stderr, "sempose run: cannot write histograms to %s: %s\n", dir.c_str(), why);
  return why;
}

// The signals that stop a run cleanly: every one whose default action would end the process
// and that comes from outside (cli_signals.hpp) but SIGUSR1, which dumps the histograms.
// SIGHUP too: an operator's ssh session or terminal closing used to kill `sempose run` with the
// default action, mid-line in the CSV and with the candump log and histograms unwritten; and
// SIGQUIT, SIGALRM, SIGUSR2 (and the rest of the list) did so until the third round.
bool is_stop_signal(int sig) {
  static const sigset_t stop = [] {
    sigset_t s = cli::termination_signals();
    sigdelset(&s, SIGUSR1);
    return s;
  }();
  return sig > 0 && sigismember(&stop, sig) == 1;
}

const char* stop_signal_name(int sig) {
  static char buf[24];
  return sempose::cli::signal_name(sig, buf);
}

// A stop signal that arrived while setup ran (signals are blocked, so it waits): taken
// here so a stop request during a long setup is honoured between phases, not after start.
int pending_stop_signal(const sigset_t& signals) {
  sigset_t pending;
  sigemptyset(&pending);
  if (sigpending(&pending) != 0) return 0;
  for (int sig = 1; sig < NSIG; ++sig) {
    if (is_stop_signal(sig) && sigismember(&pending, sig) == 1 && sigismember(&signals, sig) == 1) {
      const timespec zero{0, 0};
      sigset_t one;
      sigemptyset(&one);
      sigaddset(&one, sig);
      sigtimedwait(&one, nullptr, &zero);  // consume it
      return sig;
    }
  }
  return 0;
}

// The main loop and the threads setup makes (the learned appearance's worker) are not RT: a
// launcher's real-time policy (`chrt -f 5`, a unit's CPUSchedulingPolicy=) was inherited by all
// of them, while the placement lines said SCHED_OTHER (found probing). Said and dropped; the
// stages take their own policy from pipeline.*.priority.
void drop_inherited_rt_policy() {
  int policy = SCHED_OTHER;
  sched_param param{};
  if (pthread_getschedparam(pthread_self(), &policy, &param) != 0 || (policy != SCHED_FIFO && policy != SCHED_RR)) return;
  const sched_param normal{};
  const int rc = pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  std::printf("note: started under %s %d: the main loop and setup's threads %s SCHED_OTHER (the stages' policies are "
              "pipeline.*.priority)\n", policy == SCHED_FIFO ? "SCHED_FIFO" : "SCHED_RR", param.sched_priority,
              rc == 0 ? "run" : "could not be set to");
}

void pin_non_rt_thread(int cpu) {
  if (cpu < 0) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  // A core that does not exist or is outside the cpuset: said, as for the RT stages (it used
  // to be left unpinned without a word).
  if (const int rc = pthread_setaffinity_np(pthread_self(), sizeof set, &set); rc != 0) {
    std::fprintf(stderr, "warning: pipeline.non_rt_cpu: cannot pin the main thread to cpu %d (%s: offline, missing or "
                 "outside this cpuset); not pinned\n", cpu, std::strerror(rc));
  }
}

}  // namespace

int sempose::cli::run(int argc, char** argv) {
  // --duration: NaN would run forever and 1e10 s overflows the nanosecond deadline: a finite
  // number of seconds up to ten years (0: until a signal).
  const ParsedOptions parsed = parse_options({text("--config", true), real("--duration", 0, kMaxDurationS, "seconds"),
                                              flag("--strict-rt"), text("--hist-dir"), text("--can-log")},
                                             argc, argv);
  if (const int code = finish_parse("run", parsed, usage); code >= 0) return code;
  // A stdout or stderr nobody reads must not stall the main loop (CSV flushing, watchdog,
  // signals): status lines it cannot take are dropped and counted (stdout_lines_lost).
  session::make_stdio_nonblocking();
  const Options opt{parsed.text("--config"), parsed.real("--duration", 0), parsed.has("--strict-rt"),
                    parsed.text("--hist-dir"), parsed.text("--can-log")};

  // Signals: blocked from the very start and everywhere (threads inherit the mask), taken
  // with sigtimedwait, so a SIGINT/SIGTERM/SIGHUP in any phase of start-up is a clean stop.
  sigset_t signals = termination_signals();  // the stop signals and SIGUSR1
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  config::AppConfig cfg;
  std::string errors;
  if (!config::load_app_config(opt.config, cfg, errors)) {
    std::fprintf(stderr, "sempose run: invalid config:\n%s", errors.c_str());
    return 2;
  }
  const bool strict = opt.strict_rt || cfg.pipeline.strict_rt;
  if (strict) {
    // Strict: the preflight first; a failing check would make the RT guarantee a lie.
    std::printf("sempose run: --strict-rt: checking the system first (sempose check-rt)\n");
    if (print_rt_checks(cfg, "/") == 3) {
      std::fprintf(stderr, "sempose run: --strict-rt: refusing to start, see the FAIL lines and their fixes above\n");
      return 3;
    }
  }
  const std::string hist_dir = opt.hist_dir.empty() ? cfg.output.hist_dir : opt.hist_dir;


  // Output paths given on the command line get the same checks as the config's, before any
  // setup work and before any file is created or truncated.
  {
    std::string bad;
    if (const std::string ctl = config::control_character_problem(opt.can_log); !ctl.empty()) {
      bad += "  --can-log: " + ctl + "\n";
    } else if (opt.can_log == "-") {
      bad += "  --can-log: '-' (standard output) is not supported here: stdout carries the run's status lines; name a file\n";
    } else if (!opt.can_log.empty()) {
      if (const std::string why = config::output_path_problem(opt.can_log); !why.empty())
        bad += "  --can-log: '" + opt.can_log + "' cannot be written: it is " + why + "\n";
    }
    if (const std::string ctl = config::control_character_problem(opt.hist_dir); !ctl.empty()) {
      bad += "  --hist-dir: " + ctl + "\n";
    } else if (opt.hist_dir == "-") {
      // As --can-log: '-' reads as standard output elsewhere; a folder named '-' was made.
      bad += "  --hist-dir: '-' (standard output) is not a folder: histograms are files; name a directory\n";
    } else if (!opt.hist_dir.empty()) {
      if (const std::string why = config::output_dir_problem(opt.hist_dir); !why.empty())
        bad += "  --hist-dir: '" + opt.hist_dir + "' cannot hold histograms: it is " + why + "\n";
    }
    // No output may be one of the run's inputs, nor the other output (two writers on one file).
    std::vector<NamedPath> inputs = {{"the config", opt.config}};
    for (std::size_t i = 0; i < cfg.targets.size(); ++i) {
      for (std::size_t j = 0; j < cfg.targets[i].pattern_sets.size(); ++j) {
        const std::string key = "targets[" + std::to_string(i) + "].pattern_sets[" + std::to_string(j) + "].";
        inputs.push_back({key + "file", cfg.targets[i].pattern_sets[j].file});
        inputs.push_back({key + "mask", cfg.targets[i].pattern_sets[j].mask});
      }
    }
    for (std::size_t i = 0; i < cfg.sim.targets.size(); ++i) {
      inputs.push_back({"sim.targets[" + std::to_string(i) + "].texture.path", cfg.sim.targets[i].texture.path});
    }
    inputs.push_back({"sim.background.path", cfg.sim.background.path});
    if (cfg.source == "replay") add_recording(inputs, "replay.frames_dir", cfg.replay.frames_dir);
    const std::string can_log = opt.can_log.empty() && cfg.can.interface.empty() ? cfg.can.log_file : opt.can_log;
    const char* can_log_key = opt.can_log.empty() ? "can.log_file" : "--can-log";
    // The two files a run writes, by the key that names them.
    const std::pair<const char*, std::string> file_outputs[] = {{"output.poses_csv", cfg.output.poses_csv}, {can_log_key, can_log}};
    for (const auto& [key, path] : file_outputs) {
      if (const std::string why = output_overwrites_input(key, path, inputs); !why.empty()) bad += "  " + why + "\n";
    }
    if (const std::string why = cli::stream_overwrites_input(inputs); !why.empty()) bad += "  " + why + "\n";
    // A new .pgm in the recording's frames folder is read as a frame by the next replay or run
    // of it (found probing: output.poses_csv REC/frame_999999.pgm, or --can-log REC/zz.pgm, ran
    // and every replay of REC after failed on its "wrong magic"). Through a link too.
    if (cfg.source == "replay") {
      for (const auto& [key, path] : file_outputs) {
        if (!path.empty() && path != "-" && hal::is_pgm_name(cli::resolved_output(path).string()) &&
            cli::output_in_folder(path, cfg.replay.frames_dir)) {
          bad += std::string("  ") + key + ": '" + path + "' is a PGM in the recording's frames folder " + cfg.replay.frames_dir +
                 " (replay.frames_dir): it would be read as a frame; name the file otherwise\n";
        }
      }
    }
    for (const auto& [key, path] : file_outputs) {
      if (const char* stream = cli::standard_stream_named(path)) {
        bad += std::string("  ") + key + ": '" + path + "' is this process's " + stream +
               ", which carries the run's status lines and warnings: the two would be written over each other; name a file\n";
      }
    }
    // output.keep_previous copies each over NAME.1: that must not be an input or the other output.
    if (cfg.output.keep_previous) {
      for (const auto& [key, path, other] : {std::tuple<const char*, std::string, std::string>{"output.poses_csv", cfg.output.poses_csv, can_log},
                                             {can_log_key, can_log, cfg.output.poses_csv}}) {
        if (path.empty() || path == "-" || cli::is_null_device(path)) continue;
        const std::string kept = path + ".1";
        if (const std::string why = output_overwrites_input(std::string(key) + "'s kept copy (output.keep_previous)", kept, inputs);
            !why.empty()) {
          bad += "  " + why + "\n";
        } else if (cli::same_output(kept, other)) {
          bad += std::string("  ") + key + "'s kept copy '" + kept + "' (output.keep_previous) is the other output '" + other +
                 "': name the files otherwise\n";
        }
      }
    }
    if (cli::same_output(can_log, cfg.output.poses_csv)) {  // the same path, a hard or symbolic link
      bad += std::string("  ") + can_log_key + ": '" + can_log + "' is also output.poses_csv: the CAN log and the poses " +
             "would be written into one file; name two files\n";
    }
    // The histograms are written at exit (and on SIGUSR1) into hist_dir under fixed names: a
    // CSV or CAN log of such a name there was overwritten by them, the whole run's poses gone.
    // The same for the names the dump writes first and renames (found probing: a CSV named
    // latency_hist.txt.part was truncated by the dump, then renamed away: no CSV anywhere), and
    // for this process's standard streams (`run --hist-dir h > h/latency_hist.txt`: the captured
    // status lines and summary renamed over at exit).
    for (const std::string& name : {std::string(kHistogramTxt), std::string(kHistogramJson),
                                    std::string(kHistogramTxt) + ".part", std::string(kHistogramJson) + ".part"}) {
      if (hist_dir.empty()) break;
      const std::string hist = hist_dir + "/" + name;
      if (const char* stream = cli::standard_stream_named(hist)) {
        bad += std::string("  ") + (opt.hist_dir.empty() ? "output.hist_dir" : "--hist-dir") + ": the histogram file " + hist +
               " is this process's " + stream + ", which carries the run's status lines: it would be written over at exit; " +
               "name another folder\n";
      }
      for (const auto& [key, path] : file_outputs) {
        if (cli::same_output(path, hist)) {
          bad += std::string("  ") + key + ": '" + path + "' is the histogram file " + hist + " (" +
                 (opt.hist_dir.empty() ? "output.hist_dir" : "--hist-dir") + "), written over it at exit; name another file\n";
        }
      }
    }
    // The histogram folder named as the CSV or the CAN log, or inside one (a path through a
    // file): the file is made at start and the folder cannot be made there at exit (found
    // probing: the whole run went, then "histograms: NOT written", exit 4).
    if (!hist_dir.empty()) {
      const std::filesystem::path folder = cli::resolved_output(hist_dir);
      for (const auto& [key, path] : file_outputs) {
        if (path.empty() || path == "-" || cli::is_null_device(path)) continue;
        const std::filesystem::path file = cli::resolved_output(path);
        if (std::mismatch(file.begin(), file.end(), folder.begin(), folder.end()).first == file.end()) {
          bad += std::string("  ") + (opt.hist_dir.empty() ? "output.hist_dir" : "--hist-dir") + ": '" + hist_dir + "' " +
                 (folder == file ? "is" : "lies inside") + " " + key + " '" + path +
                 "', a file the run writes: the histograms need a folder there; name another folder\n";
        }
      }
    }
    // A umask that takes the owner's write bit (0777, 0200): each output is created (to lock it)
    // and opened again, and the second open was refused — "cannot create: Permission denied" in
    // a folder the user may write (found probing). Root is not refused the second open.
    const mode_t mask = ::umask(0);  // read it: umask() only reads by setting
    ::umask(mask);
    const bool makes_files = (!cfg.output.poses_csv.empty() && cfg.output.poses_csv != "-") || !can_log.empty();
    if ((mask & S_IWUSR) != 0 && ::geteuid() != 0 && makes_files) {
      char text[16];
      std::snprintf(text, sizeof text, "%04o", static_cast<unsigned>(mask & 0777));
      bad += std::string("  the process's umask ") + text + " leaves the owner no write permission on the files the run " +
             "creates, and it opens each of them twice: run it with umask 022 or 077 (a unit's UMask=)\n";
    }
    if (!bad.empty()) {
      std::fprintf(stderr, "sempose run: invalid output:\n%s", bad.c_str());
      return 2;
    }
  }

  if (const int sig = pending_stop_signal(signals)) {
    std::printf("stopped by %s during setup (no output written)\n", stop_signal_name(sig));
    return 0;
  }
  // The main thread on its core before setup: the threads setup creates (the learned
  // appearance's worker) inherit its placement, off the RT cores. It used to be pinned after
  // setup, so the worker could run on any core, an RT stage's included.
  drop_inherited_rt_policy();
  pin_non_rt_thread(cfg.pipeline.non_rt_cpu);
  // ---- setup: everything that allocates (session::RunSetup), inputs first
  session::RunSetup run;
  rt::Status st = session::build_inputs(cfg, run);
  if (!st) {
    std::fprintf(stderr, "sempose run: %s\n", config::terminal_text(st.message).c_str());
    return 2;
  }
  // A recording sets the field: the stall rule the config was checked against with
  // scan.field_w/h holds for the field the start search will scan (found probing: a 4096²
  // recording under the 2 s default, every start search reported as a stall, heartbeat LOST).
  if (const std::string why = config::stall_timeout_problem(cfg.service, run.scan->limits(), cfg.governor.initial_dwell_ns);
      !why.empty()) {
    std::fprintf(stderr, "sempose run: service.stall_timeout_ms: %s (the field is the source's, not scan.field_w/h)\n",
                 why.c_str());
    return 2;
  }
  // Setup is done up to the outputs: a stop signal that came meanwhile stops here, before
  // any output file is created or truncated.
  if (const int sig = pending_stop_signal(signals)) {
    std::printf("stopped by %s during setup (no output written)\n", stop_signal_name(sig));
    return 0;
  }
  // The stages' threads are tried before any output is touched: under a thread limit their
  // creation failed only after the CSV and the candump log had been emptied (found probing).
  st = rt::try_thread_room(cfg.pipeline.output_on_correlation_thread ? 2 : 3, rt::RtThreadConfig{}.stack_bytes, "the pipeline");
  if (!st) {
    std::fprintf(stderr, "sempose run: %s (no output touched)\n", config::terminal_text(st.message).c_str());
    return 3;
  }
  // The histograms' snapshots for the status lines, SIGUSR1 dumps and the summary, made once here:
  // the main loop and the report at exit refresh them without allocating (under `ulimit -v` just
  // above the run's need, a status line's snapshot threw std::bad_alloc mid-run and the run ended
  // without its summary; found probing). Made before the outputs are touched, from histograms of
  // the pipeline's fixed sizes: running out of memory here leaves the last run's files whole.
  std::vector<rt::HistogramSnapshot> snapshots;
  rt::HistogramSnapshot e2e_now;
  {
    const pipeline::PipelineHistograms sizes;
    snapshots = sizes.snapshot();
    e2e_now = sizes.end_to_end.snapshot();
  }
  st = session::build_outputs(cfg, opt.can_log, hist_dir, run);
  if (!st) {
    std::fprintf(stderr, "sempose run: %s\n", config::terminal_text(st.message).c_str());
    return 2;
  }
  pipeline::Pipeline* pipe = run.pipeline.get();

  const hal::ScanLimits& field = run.scan->limits();
  std::printf("sempose run: config %s, source %s%s%s, %dx%d field, %zu target(s)\n", opt.config.c_str(), cfg.source.c_str(),
              run.clock->real_time() ? "" : " (virtual time)", run.frame_sync ? " + GPIO frame sync" : "", field.field_w,
              field.field_h, run.trackers.trackers.size());
  // A recording's frames set the field: a scan.field_w/h that says otherwise is not used.
  if (field.field_w != cfg.scan.field_w || field.field_h != cfg.scan.field_h) {
    std::printf("note: the field is the source's %dx%d, not scan.field_w/h %dx%d\n", field.field_w, field.field_h,
                cfg.scan.field_w, cfg.scan.field_h);
  }
  // A modelled compute longer than the longest ROI scan: in virtual time (lock step, no frame
  // dropped) every frame waits for the pose before it, so the queue and the end-to-end latency
  // grow for the whole run (found probing: 318 s end-to-end in a 2 s run, dropped=0), where a
  // live pipeline would drop frames. Said, so the latencies are not read as measured.
  if (pipeline::uses_virtual_clock(cfg) && cfg.pipeline.virtual_compute_ns > 0) {
    const int roi = std::min({cfg.tracker.roi_size_px, field.field_w, field.field_h});
    const std::uint32_t dwell = cfg.governor.max_dwell_ns > 0 ? cfg.governor.max_dwell_ns : field.max_dwell_ns;
    const std::int64_t longest = field.scan_time_ns(roi, roi, dwell);
    if (static_cast<std::int64_t>(cfg.pipeline.virtual_compute_ns) > longest) {
      std::printf("warning: pipeline.virtual_compute_ns %u ns is longer than the longest ROI scan (%.1f ms: %dx%d at %u ns): "
                  "in virtual time each frame waits for the pose before it, so queue and end-to-end latency grow for the "
                  "whole run (a live pipeline would drop frames)\n",
                  cfg.pipeline.virtual_compute_ns, longest * 1e-6, roi, roi, dwell);
    }
  }
  const auto* comedi = dynamic_cast<const hal::ComediScanSource*>(run.source.get());
  if (comedi != nullptr) std::printf("comedi: %s\n", comedi->description().c_str());
  for (std::size_t i = 0; i < run.trackers.names.size(); ++i) {
    std::printf("  target %zu %s: pattern %s\n", i, run.trackers.names[i].c_str(), run.trackers.pattern_origins[i].c_str());
  }
  for (const std::string& note : run.trackers.symmetry_notes) std::printf("note: %s\n", note.c_str());
  // A pattern set without nm_per_px is 1 nm per pixel: CAN then carries pixels labelled nm, in
  // whole pixels (POSE_XY's 1 nm step), and nothing said so (hostile round 11).
  for (std::size_t i = 0; i < cfg.targets.size(); ++i) {
    for (std::size_t j = 0; j < cfg.targets[i].pattern_sets.size(); ++j) {
      if (cfg.targets[i].pattern_sets[j].nm_per_px_given) continue;
      std::printf("note: targets[%zu].pattern_sets[%zu].nm_per_px not given: 1 nm per pixel, so CAN carries this target's "
                  "positions in pixels, rounded to whole pixels in POSE_XY (give the magnification step's nm/px)\n",
                  i, j);
    }
  }
  std::printf("memory: pattern banks + spectra %.1f MiB, frame pool %.1f MiB\n", run.trackers.memory_bytes / 1048576.0,
              pipe->frame_pool_bytes() / 1048576.0);
  std::printf("output: %s%s%s\n", run.can.description.c_str(), run.csv ? ", CSV " : "",
              run.csv ? cfg.output.poses_csv.c_str() : "");
  for (const std::string& note : run.output_notes) std::printf("%s\n", note.c_str());

  // ---- RT memory and latency setup, then start
  if (cfg.pipeline.lock_memory) {
    st = rt::lock_process_memory(strict);
    if (!st) {
      std::fprintf(stderr, "sempose run: %s\n", config::terminal_text(st.message).c_str());
      return 3;
    }
    if (!st.message.empty()) std::printf("warning: %s\n", config::terminal_text(st.message).c_str());
  }
  rt::CpuDmaLatencyHold dma;
  if (cfg.pipeline.hold_dma_latency) {
    st = dma.acquire(strict);
    if (!st) {
      std::fprintf(stderr, "sempose run: %s\n", config::terminal_text(st.message).c_str());
      return 3;
    }
    if (!st.message.empty()) std::printf("warning: %s\n", config::terminal_text(st.message).c_str());
  }
  if (const int sig = pending_stop_signal(signals)) {
    std::printf("stopped by %s during setup\n", stop_signal_name(sig));
    return 0;
  }
  // rt_allocs: heap calls on armed (RT) threads from here on; setup may allocate freely.
  const std::uint64_t allocs_at_start = rt::alloc::allocations();
  st = pipe->start(strict);
  if (!st) {
    std::fprintf(stderr, "sempose run: %s\n", config::terminal_text(st.message).c_str());
    return 3;
  }
  for (const auto& p : pipe->placements()) std::printf("thread %s\n", p.c_str());
  for (const auto& w : pipe->warnings()) std::printf("warning: %s\n", w.c_str());
  for (const auto& w : run.trackers.warnings) std::printf("warning: %s\n", w.c_str());

  // systemd (Type=notify): READY once setup is done; the watchdog is fed from this loop only
  // while every stage makes progress. Without NOTIFY_SOCKET these are no-ops.
  service::SystemdNotifier notifier = service::SystemdNotifier::from_environment();
  if (!notifier.problem().empty()) std::printf("warning: %s\n", config::terminal_text(notifier.problem()).c_str());
  service::PipelineWatchdog watchdog(*pipe, notifier, static_cast<std::int64_t>(cfg.service.stall_timeout_ms) * rt::kNsPerMs,
                                     rt::now_ns());
  if (notifier.enabled() && !notifier.ready("running")) {
    // A NOTIFY_SOCKET nobody listens on (a missing path, a regular file): "READY sent" was
    // printed regardless (found probing), while systemd would time the start out.
    const int err = errno;
    const char* socket = std::getenv("NOTIFY_SOCKET");
    std::printf("warning: systemd: READY could not be sent to NOTIFY_SOCKET '%s' (%s): a Type=notify unit will time "
                "this start out\n", config::terminal_text(socket ? socket : "").c_str(), std::strerror(err));
  } else if (notifier.enabled()) {
    std::printf("systemd: READY sent%s\n", notifier.watchdog_interval_ns() > 0
                                              ? (", watchdog every " + std::to_string(notifier.watchdog_interval_ns() / 2'000'000) +
                                                 " ms while every stage progresses").c_str()
                                              : "");
  }
  std::fflush(stdout);

  // ---- non-RT loop: signals, periodic flush and status
  const std::int64_t t0 = rt::now_ns();
  const auto duration_ns = static_cast<std::int64_t>(opt.duration_s * 1e9);  // <= 3.2e17: no overflow
  const std::int64_t period_ns = static_cast<std::int64_t>(cfg.pipeline.stats_period_ms) * rt::kNsPerMs;
  std::int64_t next_status = t0 + period_ns;
  const auto& c = pipe->counters();
  int stop_signal = 0;
  bool can_detached = false;
  bool ring_overflow_said = false;
  pipeline::StallWatchdog source_watchdog(pipeline::StallWatchdog::timeout_for(run.scan->limits()), t0);
  // Out of memory here (the status line's and the dump's formatting may allocate; an address-space
  // limit just above the run's need) stops the run like a stop signal: the stages drain, the
  // outputs close and the summary says why, instead of an exception leaving them running.
  bool out_of_memory = false;
  try {
    while (!pipe->finished()) {
      const std::int64_t now = rt::now_ns();
      // Stall watchdog (non-RT): frames must keep coming while running. Virtual-time sources
      // run as fast as the CPU allows, so the same wall-clock bound holds for them.
      switch (source_watchdog.update(c.frames_scanned.get(), now)) {
        case pipeline::StallWatchdog::Change::kStalled:
          pipe->set_fault(pipeline::kFaultSourceStalled, true);
          std::printf(
              "fault: the scan source delivered no frame for %.1f s (scan_errors=%llu); state "
              "reported LOST\n",
              source_watchdog.silent_ns(now) * 1e-9,
              static_cast<unsigned long long>(c.scan_errors.get()));
          std::fflush(stdout);
          break;
        case pipeline::StallWatchdog::Change::kRecovered:
          pipe->set_fault(pipeline::kFaultSourceStalled, false);
          std::printf("fault cleared: the scan source delivers frames again\n");
          std::fflush(stdout);
          break;
        case pipeline::StallWatchdog::Change::kNone:
          break;
      }
      if (opt.duration_s > 0 && now - t0 >= duration_ns) break;
      const std::int64_t until = std::min(next_status, watchdog.next_due_ns());
      const timespec wait = rt::to_timespec(
          std::min<std::int64_t>(50 * rt::kNsPerMs, std::max<std::int64_t>(0, until - now)));
      const int sig = sigtimedwait(&signals, nullptr, &wait);
      if (is_stop_signal(sig)) {
        stop_signal = sig;
        break;
      }
      if (sig == SIGUSR1) {
        const char* why_not = dump_histograms(hist_dir, *pipe, snapshots);
        if (why_not == nullptr) {
          std::printf("histograms written to %s\n", hist_dir.empty() ? "(no --hist-dir)" : hist_dir.c_str());
        } else {
          std::printf("histograms NOT written to %s (%s)\n", hist_dir.c_str(), why_not);
        }
      }
      if (rt::now_ns() >= watchdog.next_due_ns()) watchdog.poll(rt::now_ns());
      // The outputs' rings are emptied on every wake (at most 50 ms apart), not once a status
      // period: with stats_period_ms 60000 the default 1 MiB candump ring held 6468 of 9650 poses'
      // lines and the rest were dropped (hostile round 11).
      run.flush_outputs();
      if (run.output_write_errors() > 0 && !(pipe->faults() & pipeline::kFaultOutputWrite)) {
        pipe->set_fault(pipeline::kFaultOutputWrite, true);
        std::printf("fault: writing an output file failed (%s)\n",
                    std::strerror(run.last_output_errno()));
        std::fflush(stdout);
      }
      if (!ring_overflow_said && run.output_ring_overflowed()) {
        ring_overflow_said = true;
        std::printf("fault: an output's ring overflowed between flushes: poses or log lines dropped (counted in "
                    "csv_lines_lost / can_log_bytes_lost; raise output.csv_buffer_poses or can.log_buffer_bytes)\n");
        std::fflush(stdout);
      }
      // The CAN interface went away (unplugged adapter, `ip link del`) or came back and was
      // bound again by flush_outputs(): said once each way.
      if (run.can.channel->detached() != can_detached) {
        can_detached = !can_detached;
        if (can_detached)
          std::printf(
              "fault: CAN interface %s is gone; poses and heartbeats are not sent (counted) "
              "until it is back\n",
              run.can.channel->name());
        else
          std::printf("fault cleared: CAN interface %s is back and bound again\n",
                      run.can.channel->name());
        std::fflush(stdout);
      }
      if (rt::now_ns() >= next_status) {
        // After a time jump (SIGSTOP, a suspended VM) one status line, not one per missed period.
        next_status = std::max(next_status + period_ns, rt::now_ns() + period_ns);
        if (cfg.output.print_status) {
          pipe->histograms().end_to_end.snapshot_into(e2e_now);
          const rt::HistogramSnapshot& e2e = e2e_now;
          std::printf(
              "t=%.1fs frames=%llu poses=%llu dropped=%llu overruns=%llu dwell_ns=[%llu,%llu] "
              "e2e_us_p99=%.0f "
              "output_errors=%llu%s\n",
              (rt::now_ns() - t0) * 1e-9, static_cast<unsigned long long>(c.frames_scanned.get()),
              static_cast<unsigned long long>(c.sent.get()),
              static_cast<unsigned long long>(pipe->dropped_frames()),
              static_cast<unsigned long long>(c.overruns.get()),
              static_cast<unsigned long long>(c.dwell_min_ns.get()),
              static_cast<unsigned long long>(c.dwell_max_ns.get()), e2e.percentile_us(0.99),
              static_cast<unsigned long long>(run.output_write_errors()),
              source_watchdog.stalled() ? " STALLED" : "");
          std::fflush(stdout);
        }
      }
    }
  } catch (const std::bad_alloc&) {
    out_of_memory = true;
    std::printf(
        "fault: out of memory in the non-RT loop (an address-space limit: ulimit -v, RLIMIT_AS); "
        "stopping\n");
    std::fflush(stdout);
  }
  // What follows (stop line, histograms, summary) may wait a little for a slow reader, in all
  // at most 2 s: the run has stopped, and a reader that never reads must not keep it alive.
  session::set_stdio_patience_ms(2000);
  notifier.stopping();
  pipe->request_stop();
  // Drain within a bound: a stage stuck in a driver must not keep the service from stopping.
  const std::int64_t drain_deadline = rt::now_ns() + static_cast<std::int64_t>(cfg.service.stop_timeout_ms) * rt::kNsPerMs;
  while (!pipe->finished() && rt::now_ns() < drain_deadline) rt::sleep_until_ns(rt::now_ns() + 5 * rt::kNsPerMs);
  if (!pipe->finished()) {
    run.flush_outputs();
    dump_histograms(hist_dir, *pipe, snapshots);
    std::printf("sempose run: the stages did not drain within service.stop_timeout_ms=%u ms; exiting without them\n",
                cfg.service.stop_timeout_ms);
    std::fflush(stdout);
    std::_Exit(6);  // joining would wait for the stuck stage forever
  }
  pipe->join();
  // The run's time up to the stages' end, their drain included: the poses they make draining are
  // counted, and a stop already pending as the loop began gave `poses=2 poses_per_s=394633.0
  // duration_s=0.00` over the microseconds before the drain (found probing).
  const double run_s = (rt::now_ns() - t0) * 1e-9;
  run.sink->flush();
  const bool csv_ok = run.csv ? run.csv->close() : true;
  if (stop_signal != 0) std::printf("stopped by %s\n", stop_signal_name(stop_signal));
  if (pipe->source_ended()) std::printf("the source ended\n");
  const char* hist_why_not = dump_histograms(hist_dir, *pipe, snapshots);

  // ---- summary
  pipe->histograms().snapshot_into(snapshots);
  for (const auto& s : snapshots) {
    // dwell_ns is recorded with 1 ns per bucket (see pipeline_stats.hpp): its unit is ns.
    const char* unit = s.name == "dwell_ns" ? "ns" : "us";
    std::printf("%-7s %-10s n=%llu min=%.1f%s p50=%.0f%s p99=%.0f%s p99.9=%.0f%s max=%.1f%s\n",
                s.name == "dwell_ns" ? "dwell" : "latency", s.name.c_str(),
                static_cast<unsigned long long>(s.count), s.min_ns / 1e3, unit, s.percentile_us(0.5), unit,
                s.percentile_us(0.99), unit, s.percentile_us(0.999), unit, s.max_ns / 1e3, unit);
  }
  for (int t = 0; t < pipe->target_count(); ++t) {
    const auto& tc = c.targets[static_cast<std::size_t>(t)];
    std::printf("target %d %s: poses=%llu poses_per_s=%.1f tracked_share=%.3f start_searches=%llu\n", t,
                run.trackers.names[static_cast<std::size_t>(t)].c_str(), static_cast<unsigned long long>(tc.poses.get()),
                tc.poses.get() / run_s, tc.poses.get() ? double(tc.tracked.get()) / tc.poses.get() : 0.0,
                static_cast<unsigned long long>(tc.searches.get()));
    if (cfg.tracker.appearance.enabled) {
      const pose::Tracker::AppearanceStatus a = run.trackers.trackers[static_cast<std::size_t>(t)]->appearance_status();
      std::printf("appearance %d %s: updates=%u rejected=%u deferred=%u support_fraction=%.2f template_updates=%u "
                  "template_weight=%.2f\n",
                  t, run.trackers.names[static_cast<std::size_t>(t)].c_str(), a.accepted, a.rejected, a.deferred,
                  a.support_fraction, a.template_updates, a.template_weight);
    }
    session::print_detector_report(stdout, t, run.trackers.names[static_cast<std::size_t>(t)],
                                   run.trackers.trackers[static_cast<std::size_t>(t)]->detector_tau_status());
  }
  if (hist_dir.empty()) {
    std::printf("histograms: not written (no --hist-dir / output.hist_dir)\n");
  } else if (hist_why_not != nullptr) {
    std::printf("histograms: NOT written to %s (%s)\n", hist_dir.c_str(), hist_why_not);
  } else {
    std::printf("histograms: %s/latency_hist.txt (cyclictest layout), %s/latency_hist.json\n", hist_dir.c_str(),
                hist_dir.c_str());
  }
  if (comedi != nullptr) {
    const auto& k = comedi->counters();
    std::printf("comedi: scans=%llu stopped_early=%llu timeouts=%llu arm_errors=%llu cancelled=%llu (beam parked)\n",
                static_cast<unsigned long long>(k.scans), static_cast<unsigned long long>(k.stopped),
                static_cast<unsigned long long>(k.timeouts),
                static_cast<unsigned long long>(k.arm_errors), static_cast<unsigned long long>(k.cancelled));
  }
  if (watchdog.ping_failures() > 0) {
    std::printf("warning: systemd: %llu of %llu watchdog pings could not be sent to NOTIFY_SOCKET\n",
                static_cast<unsigned long long>(watchdog.ping_failures()),
                static_cast<unsigned long long>(watchdog.ping_failures() + watchdog.pings()));
  }
  session::RunSummary summary = session::collect_summary(
      run, e2e_now, run_s, rt::alloc::allocations() - allocs_at_start, source_watchdog.stalls());
  summary.stdout_lines_lost = session::stdout_lines_lost();
  session::print_summary(stdout, summary);
  if (session::stdout_lines_lost() > summary.stdout_lines_lost || cli::stdout_started_closed()) {
    // The summary itself did not get through: stderr has it (a different reader, often a log).
    std::fprintf(stderr, "sempose run: standard output is blocked or closed; the summary:\n");
    session::print_summary(stderr, summary);
  }
  // Exit code: 0 only when nothing was lost. 4: an output failed to write; 5: the source stalled;
  // 6 (above): the stages did not drain within service.stop_timeout_ms; 7: memory ran out in the
  // non-RT loop and the run was stopped early.
  if (out_of_memory) {
    std::fprintf(
        stderr,
        "sempose run: stopped early: out of memory in the non-RT loop (ulimit -v, RLIMIT_AS)\n");
    return 7;
  }
  if (summary.output_errors > 0 || !csv_ok || summary.can_log_bytes_lost > 0 || hist_why_not != nullptr) {
    std::fprintf(stderr, "sempose run: output write errors (csv lines lost %llu, candump log bytes lost %llu%s)\n",
                 static_cast<unsigned long long>(summary.csv_lines_lost),
                 static_cast<unsigned long long>(summary.can_log_bytes_lost), hist_why_not == nullptr ? "" : ", histograms not written");
    return 4;
  }
  if (source_watchdog.stalls() > 0) {
    std::fprintf(stderr, "sempose run: the scan source stalled %llu time(s)\n",
                 static_cast<unsigned long long>(source_watchdog.stalls()));
    return 5;
  }
  return 0;
}
