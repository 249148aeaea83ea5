// `sempose replay --frames DIR --pattern P.pgm [--mask M.pgm] [--pattern Q.pgm ...] [--config FILE]
//                 [--truth ground_truth.csv] --out poses.csv`
// Tracks through a recorded sequence (README: Replay and recording) on the offline runner:
// the recording is a ReplaySource on the virtual clock (every scan is the requested ROI cut
// from the next full-field frame), the trackers come from the same setup as `sempose run`'s
// and the poses go through the same CsvPoseSink, so the CSV is the pipeline's:
// frame,t_ns,x_px,y_px,phi_deg,score,status[,target],scale (t_ns = scan end, target = index).
// Each target starts with a full-field search (no start pose needed). Ends with one line
//   summary: frames=N tracked_share=F compute_us_p50=A compute_us_p99=B compute_us_max=C acquire_ms=D
// compute = the tracker's update() per ROI pose (wall time, file I/O excluded); acquire = the
// first full-field search. With --truth: RMS/max position and angle errors over TRACKING
// poses, the TRACKING poses > 3 px or > 10° off (false_tracking) and those on a frame the truth
// has no row for (tracking_without_truth), on a line before the summary.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "cli.hpp"
#include "cli_signals.hpp"
#include "cli_options.hpp"
#include "sempose/config/app_config.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/target_name.hpp"
#include "sempose/hal/frames_csv.hpp"
#include "sempose/hal/replay_source.hpp"
#include "sempose/pipeline/csv_pose_sink.hpp"
#include "sempose/pipeline/offline_runner.hpp"
#include "sempose/pipeline/tracker_setup.hpp"
#include "sempose/session/detector_report.hpp"
#include "sempose/session/run_setup.hpp"
#include "sempose/pose/tracker.hpp"

namespace {

using namespace sempose;

int usage(std::FILE* out) {
  std::fprintf(out,
               "usage: sempose replay --frames DIR --pattern P.pgm [--mask M.pgm] [--pattern Q.pgm ...] [--config FILE]\n"
               "                      [--truth ground_truth.csv] --out poses.csv\n"
               "  --out:    the poses' CSV; - writes it to standard output (the report then goes to stderr)\n"
               "  tracks every pattern (one target each) through the recorded full-field frames in DIR\n"
               "  --config: YAML; its tracker: section (and targets:, when no --pattern is given) are used\n"
               "  --mask:   the preceding pattern's shape mask (PGM, same size; non-zero = the target)\n"
               "  --truth:  frame,x_px,y_px,phi_deg[,target]; prints RMS/max errors\n");
  return out == stdout ? 0 : 2;
}

// The replay's CSV and the poses written to it, for stop_replay().
pipeline::CsvPoseSink* g_csv = nullptr;
std::string g_out_path;
std::uint64_t g_poses = 0;

struct Truth {
  double x = 0, y = 0, phi = 0;
};

// Passes every pose on to the CSV and compares TRACKING poses with the --truth rows of their
// (frame, target).
class TruthCheckSink final : public pipeline::PoseSink {
 public:
  TruthCheckSink(pipeline::PoseSink& out, const std::map<std::pair<long, int>, Truth>& truth, bool truth_given)
      : out_(out), truth_(truth), truth_given_(truth_given) {}
  pipeline::PublishResult publish(const pipeline::PoseRecord& p, std::int64_t t_now_ns) noexcept override {
    const auto it = truth_.find({static_cast<long>(p.frame_seq), static_cast<int>(p.target)});
    if (it != truth_.end() && p.state == pose::TrackState::kTracking) {
      const double d = std::hypot(p.x_px - it->second.x, p.y_px - it->second.y);
      // Wrapped whatever the two angles' size (a truth of φ + 720° read 361° off through fmod),
      // and modulo the turn the pose declares its target to look the same at (angle_order: the
      // benchmark's rule, pose_accuracy_bench).
      const double a = std::fabs(std::remainder(p.phi_deg - it->second.phi, 360.0 / std::max(1, static_cast<int>(p.angle_order))));
      sum_px2 += d * d;
      sum_deg2 += a * a;
      max_px = std::max(max_px, d);
      max_deg = std::max(max_deg, a);
      ++compared;
      // Issue 13's rule for a pose a robot must not be driven with.
      if (d > 3.0 || a > 10.0) ++false_tracking;
    } else if (p.state == pose::TrackState::kTracking && truth_given_) {
      // No truth for this frame and target: `sempose sim` leaves a target out of a frame it is
      // not in, so this is a pose of something else; a hand-made truth may just have a gap.
      // Either way it is counted, not silently left out of the comparison.
      ++uncompared;
    }
    if (const int sig = sempose::cli::stop_requested(); sig != 0 && on_stop_ != nullptr) on_stop_(sig);
    ++g_poses;
    return out_.publish(p, t_now_ns);
  }
  // Called (not returning) with the signal when one asks the replay to stop.
  void (*on_stop_)(int) = nullptr;
  void flush() override { out_.flush(); }

  double sum_px2 = 0, max_px = 0, sum_deg2 = 0, max_deg = 0;
  long compared = 0, false_tracking = 0, uncompared = 0;

 private:
  pipeline::PoseSink& out_;
  const std::map<std::pair<long, int>, Truth>& truth_;
  bool truth_given_;  // --truth given (an empty one: the target is on no frame)
};

// A replay that did not finish (stopped by a signal, a write that failed, the run broken off):
// its CSV holds whole lines of the frames so far and would look like the replay of a shorter
// recording, so it is closed and removed (a regular file only: not standard output or a
// device). True when removed.
bool remove_incomplete_csv() {
  if (g_csv == nullptr) return false;
  g_csv->close();
  struct stat st {};
  return g_out_path != "-" && ::stat(g_out_path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::unlink(g_out_path.c_str()) == 0;
}

// Stopped by a signal: the incomplete CSV removed, and the process ends by the signal
// (cli_signals.hpp).
[[noreturn]] void stop_replay(int sig) {
  char name[24];
  const bool removed = remove_incomplete_csv();
  std::fprintf(stderr, "sempose replay: stopped by %s after %llu poses%s\n", sempose::cli::signal_name(sig, name),
               static_cast<unsigned long long>(g_poses),
               removed ? (": removed the incomplete " + g_out_path).c_str() : g_csv ? "" : ": nothing written");
  sempose::cli::end_by_signal(sig);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5))];
}

int run_replay(int argc, char** argv) {
  using cli::OptionValue, cli::ParsedOptions, cli::parse_options, cli::text;
  const ParsedOptions opt = parse_options({text("--frames", true), text("--config"), text("--truth"), text("--out", true),
                                           text("--pattern", false, true), text("--mask", false, true)},
                                          argc, argv);
  if (const int code = cli::finish_parse("replay", opt, usage); code >= 0) return code;
  // A signal stops the replay and removes the CSV begun (stop_replay).
  cli::catch_termination_signals();
  const std::string frames_dir = opt.text("--frames"), config_path = opt.text("--config"), truth_path = opt.text("--truth");
  std::string out_path = opt.text("--out");
  if (cli::refuse_control_characters("replay", "--out", out_path)) return 2;
  std::vector<std::string> patterns, masks;  // masks[i]: --mask after pattern i ("" = none)
  for (const OptionValue& v : opt.given) {
    if (v.name == "--pattern") {
      patterns.push_back(v.text);
      masks.emplace_back();
    } else if (v.name == "--mask") {
      if (patterns.empty()) {
        std::fprintf(stderr, "sempose replay: --mask must follow the --pattern it belongs to\n");
        return usage(stderr);
      }
      // A second --mask for one pattern used to replace the first without a word.
      if (!masks.back().empty()) {
        std::fprintf(stderr, "sempose replay: --mask '%s' and '%s' both follow --pattern '%s': one mask per pattern\n",
                     masks.back().c_str(), v.text.c_str(), patterns.back().c_str());
        return 2;
      }
      masks.back() = v.text;
    }
  }

  config::AppConfig app;
  app.path = "command line";  // names where the targets came from in errors when there is no --config
  if (!config_path.empty()) {
    std::string errors;
    // A run's config: its outputs are not replay's (it writes --out), so one this user cannot
    // write (the service's /var/log/sempose) is no error here.
    // Its schedule names the --pattern targets when they are given (checked below), not its own.
    if (!config::load_app_config(config_path, app, errors, config::OutputCheck::kLeaveToCaller,
                                 patterns.empty() ? config::TargetCheck::kAgainstTheConfig : config::TargetCheck::kLeaveToCaller)) {
      std::fprintf(stderr, "sempose replay: %s", errors.c_str());
      return 2;
    }
    // What a run's config names that replay passes over, said: a config naming another recording
    // than --frames replayed --frames without a word (found probing).
    std::string unused;
    auto add = [&unused](const std::string& what) { unused += (unused.empty() ? "" : ", ") + what; };
    std::error_code ec;
    if (!app.replay.frames_dir.empty() && !std::filesystem::equivalent(app.replay.frames_dir, frames_dir, ec))
      add("replay.frames_dir '" + app.replay.frames_dir + "' (--frames '" + frames_dir + "' is replayed)");
    if (app.replay.loop) add("replay.loop (a replay goes through the frames once)");
    if (!app.output.poses_csv.empty()) add("output.poses_csv '" + app.output.poses_csv + "' (the poses go to --out)");
    // A start_area or a dwell_ns given there and silently not applied (found probing).
    if (!patterns.empty() && !app.targets.empty())
      add("targets (" + std::to_string(app.targets.size()) + ", with their start_area, dwell_ns and masks: --pattern gives the targets)");
    if (!unused.empty()) std::fprintf(stderr, "note: %s: not used by replay: %s\n", config_path.c_str(), unused.c_str());
  }
  if (!patterns.empty()) {
    app.targets.clear();
    for (std::size_t i = 0; i < patterns.size(); ++i) {
      config::TargetConfig t;
      // Named after the file, kept to the rule a config's names must follow.
      std::vector<std::string> taken;
      for (const auto& other : app.targets) taken.push_back(other.name);
      t.name = config::make_target_name(std::filesystem::path(patterns[i]).stem().string(), i, taken);
      t.pattern_sets.push_back({patterns[i], 1.0, masks[i]});
      app.targets.push_back(t);
    }
  }
  if (app.targets.empty()) {
    std::fprintf(stderr, "sempose replay: no pattern: give --pattern P.pgm or targets: in --config\n");
    return 2;
  }
  if (app.targets.size() > static_cast<std::size_t>(hal::kMaxTargets)) {
    std::fprintf(stderr, "sempose replay: %zu targets, at most %d\n", app.targets.size(), hal::kMaxTargets);
    return 2;
  }
  // With --pattern the config's schedule names those targets (a target it never names would get
  // no frame and no pose, and an index beyond them none at all).
  for (std::size_t t = 0; t < app.targets.size() && !app.pipeline.schedule.empty(); ++t) {
    const auto& s = app.pipeline.schedule;
    if (std::find(s.begin(), s.end(), static_cast<int>(t)) == s.end()) {
      std::fprintf(stderr, "sempose replay: %s: pipeline.schedule never names target %zu ('%s'): it would get no frame\n",
                   config_path.c_str(), t, app.targets[t].name.c_str());
      return 2;
    }
  }
  for (const int t : app.pipeline.schedule) {
    if (t >= static_cast<int>(app.targets.size())) {
      std::fprintf(stderr, "sempose replay: %s: pipeline.schedule names target %d; there are %zu\n", config_path.c_str(), t,
                   app.targets.size());
      return 2;
    }
  }
  // --out naming this process's standard output itself (/dev/stdout, /proc/self/fd/1) is "-":
  // the report goes to stderr, as it does for "-" (found probing: opened a second time, the file
  // stdout was redirected to got the summary written over the CSV's header and first rows).
  // Standard error carries the warnings: refused.
  if (const char* stream = cli::standard_stream_named(out_path)) {
    if (std::string(stream) == "standard error") {
      std::fprintf(stderr, "sempose replay: --out '%s' is this process's standard error, which carries its warnings: name a file or '-'\n",
                   out_path.c_str());
      return 2;
    }
    out_path = "-";
  }
  // A FIFO as --out or --truth blocked in open() (found probing: the process hung); a
  // directory as --truth was read as a truth of no rows (exit 0, nothing compared).
  if (const std::string why = config::output_path_problem(out_path); out_path != "-" && !why.empty()) {
    std::fprintf(stderr, "sempose replay: --out: '%s' cannot be written: it is %s\n", out_path.c_str(), why.c_str());
    return 2;
  }
  // A missing folder: the CSV's open() failed after setup, naming output.poses_csv (a config
  // key the command line never gave). Named here by the option, before any work.
  if (std::error_code ec; out_path != "-" && !std::filesystem::path(out_path).parent_path().empty() &&
                          !std::filesystem::is_directory(std::filesystem::path(out_path).parent_path(), ec)) {
    std::fprintf(stderr, "sempose replay: --out: '%s' cannot be written: its folder '%s' does not exist (make it first)\n",
                 out_path.c_str(), std::filesystem::path(out_path).parent_path().c_str());
    return 2;
  }
  if (const std::string why = config::path_kind_problem(truth_path); !truth_path.empty() && !why.empty()) {
    std::fprintf(stderr, "sempose replay: --truth: '%s' is %s (need a CSV file: frame,x_px,y_px,phi_deg[,target])\n",
                 truth_path.c_str(), why.c_str());
    return 2;
  }
  {
    std::vector<cli::NamedPath> inputs = {{"--config", config_path}, {"--truth", truth_path}};
    for (std::size_t i = 0; i < app.targets.size(); ++i) {
      for (const auto& ps : app.targets[i].pattern_sets) {
        inputs.push_back({"the pattern of target " + std::to_string(i), ps.file});
        inputs.push_back({"the mask of target " + std::to_string(i), ps.mask});
      }
    }
    cli::add_recording(inputs, "--frames", frames_dir);
    if (const std::string problem = cli::output_overwrites_input("--out", out_path, inputs); !problem.empty()) {
      std::fprintf(stderr, "sempose replay: %s\n", problem.c_str());
      return 2;
    }
    if (const std::string problem = cli::stream_overwrites_input(inputs); !problem.empty()) {
      std::fprintf(stderr, "sempose replay: %s\n", problem.c_str());
      return 2;
    }
    if (out_path == "-" && cli::stdout_started_closed()) {
      std::fprintf(stderr, "sempose replay: --out '-': standard output is closed, and every pose line would be lost; "
                   "name a file or give the process a standard output\n");
      return 2;
    }
    // A new .pgm in the frames folder is read as a frame by the next replay of it.
    // Through a link too: where the CSV lands, and under the name it lands as.
    if (out_path != "-" && hal::is_pgm_name(cli::resolved_output(out_path).string()) &&
        cli::output_in_folder(out_path, frames_dir)) {
      std::fprintf(stderr, "sempose replay: --out '%s' is a PGM in the frames folder %s: it would be read as a frame; "
                   "name the poses' CSV otherwise\n", out_path.c_str(), frames_dir.c_str());
      return 2;
    }
  }
  // The recording, served on the virtual clock whatever the config says: offline, as fast as
  // the CPU allows, and the same inputs and time stamps as `sempose run` on it.
  session::RunSetup run;
  const rt::Status made = session::build_inputs(session::replay_config(app, frames_dir), run);
  const pipeline::TrackerSetup& trackers = run.trackers;
  if (!made.ok) {
    std::fprintf(stderr, "sempose replay: %s\n", config::terminal_text(made.message).c_str());
    return 2;
  }
  for (const auto& w : trackers.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  for (std::size_t i = 0; i < trackers.names.size(); ++i) {
    std::fprintf(stderr, "target %zu '%s': pattern bank, spectra and buffers %.1f MB\n", i, trackers.names[i].c_str(),
                 trackers.trackers[i]->memory_bytes() / 1e6);
  }
  for (const std::string& note : trackers.symmetry_notes) std::fprintf(stderr, "note: %s\n", note.c_str());

  std::map<std::pair<long, int>, Truth> truth;
  if (!truth_path.empty()) {
    std::vector<hal::TruthRow> rows;
    std::size_t non_finite = 0;
    std::string not_read;
    try {
      rows = hal::read_truth_csv(truth_path, hal::kMaxTargets, &non_finite, &not_read);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "sempose replay: --truth: %s\n", cli::error_text(e).c_str());
      return 2;
    }
    // Columns past the target (a hand-made truth with a scale, say) were read and dropped without
    // a word: a reader took the summary for a comparison of them too.
    if (!not_read.empty()) {
      std::fprintf(stderr, "sempose replay: warning: --truth '%s': only frame,x_px,y_px,phi_deg,target are compared; not "
                   "read: %s\n", truth_path.c_str(), not_read.c_str());
    }
    // Rows for frames the recording does not hold: the truth of another (longer) recording.
    const long long recorded = static_cast<long long>(hal::list_pgm_frames(frames_dir).size());
    long long beyond = 0, first_beyond = -1, untracked = 0;
    const int tracked_targets = static_cast<int>(trackers.trackers.size());
    for (const hal::TruthRow& r : rows) {
      untracked += r.target >= tracked_targets;
      if (r.frame >= recorded) {
        ++beyond;
        if (first_beyond < 0 || r.frame < first_beyond) first_beyond = r.frame;
      }
      truth[{static_cast<long>(r.frame), r.target}] = {r.x_px, r.y_px, r.phi_deg};
    }
    if (beyond > 0) {
      std::fprintf(stderr, "sempose replay: warning: --truth '%s': %lld of its %zu rows name frames the recording does not "
                   "hold (it has frames 0..%lld; the first such row is frame %lld): is it this recording's truth?\n",
                   truth_path.c_str(), beyond, rows.size(), recorded - 1, first_beyond);
    }
    // Rows of a target this replay does not track (found probing: a truth all of target 1 beside
    // one pattern compared nothing, and only tracking_without_truth said so).
    if (untracked > 0) {
      const std::string which = tracked_targets > 1 ? "targets 0.." + std::to_string(tracked_targets - 1) : "target 0";
      std::fprintf(stderr, "sempose replay: warning: --truth '%s': %lld of its %zu rows are of a target this replay does not "
                   "track (it tracks %s): they are compared with nothing\n",
                   truth_path.c_str(), untracked, rows.size(), which.c_str());
    }
    // A truth of no usable row (an empty file, a header only — `sempose sim` of a target never
    // in the field —, every row non-finite) says the target is on no frame: every TRACKING pose
    // is one without truth. It used to count none (poses_compared=0 false_tracking=0
    // tracking_without_truth=0: a clean-looking pass).
    if (truth.empty()) {
      std::fprintf(stderr, "sempose replay: warning: --truth '%s' has no usable row (frame,x_px,y_px,phi_deg[,target], "
                   "finite): the target is taken to be on no frame\n", truth_path.c_str());
    } else if (non_finite > 0) {
      // Some rows only (found probing: a nan cell dropped its frame from the comparison unsaid).
      std::fprintf(stderr, "sempose replay: warning: --truth '%s': %zu rows have a non-finite x_px, y_px or phi_deg: the "
                   "target is taken to be off those frames (a TRACKING pose there counts as tracking_without_truth)\n",
                   truth_path.c_str(), non_finite);
    }
  }

  // Every check is done: only now is the output file created (not when a signal came meanwhile).
  if (const int sig = cli::stop_requested()) stop_replay(sig);
  session::OutputLock out_lock;  // a run or another replay writing the same file: refused
  if (const rt::Status locked = out_lock.acquire("--out", out_path); !locked) {
    std::fprintf(stderr, "sempose replay: %s\n", config::terminal_text(locked.message).c_str());
    return 2;
  }
  pipeline::CsvPoseSink csv(out_path, 1024, trackers.trackers.size() > 1);
  if (const rt::Status opened = csv.open(); !opened.ok) {
    // The sink names the config key; here the file came from --out.
    std::string message = opened.message;
    if (message.rfind("output.poses_csv:", 0) == 0) message.replace(0, 17, "--out:");
    std::fprintf(stderr, "sempose replay: %s\n", config::terminal_text(message).c_str());
    return 2;
  }
  g_csv = &csv;
  // The file itself: through a link, removing the link left its target cut, whole lines that
  // look like a shorter replay (found probing).
  g_out_path = out_path == "-" ? out_path : cli::resolved_output(out_path).string();
  TruthCheckSink sink(csv, truth, !truth_path.empty());
  sink.on_stop_ = stop_replay;
  std::vector<pose::Tracker*> raw;
  for (auto& t : trackers.trackers) raw.push_back(t.get());
  pipeline::OfflineRunner runner(app.pipeline, app.governor, *run.scan, raw, sink, *run.clock);
  pipeline::OfflineRunStats stats;
  const rt::Status ran = runner.run(0, stats);
  if (!ran.ok) {
    std::fprintf(stderr, "sempose replay: %s%s\n", config::terminal_text(ran.message).c_str(),
                 remove_incomplete_csv() ? ("; removed the incomplete " + g_out_path).c_str() : "");
    return 2;
  }
  // Lines lost to a full disk or a file-size limit: the CSV's whole lines would look like the
  // replay of a shorter recording (found probing: exit 4 with "11 pose lines not written", and
  // the header and 19 whole rows left behind). Removed, as a stopped replay's is.
  if (!csv.close() || stats.publish_failures != 0) {
    const unsigned long long lost = csv.lost_lines() + csv.dropped();
    const int err = csv.last_errno();
    std::fprintf(stderr, "sempose replay: %s: %llu pose lines not written (%s)%s\n", out_path.c_str(), lost, std::strerror(err),
                 remove_incomplete_csv() ? ("; removed the incomplete file " + g_out_path).c_str() : "");
    return 4;
  }
  // With the poses on standard output (--out -) the report goes to stderr, so a pipe gets CSV only.
  const auto print_report = [&](std::FILE* report) {
    if (!truth_path.empty()) {
      const long n = sink.compared;
      std::fprintf(report, "truth: poses_compared=%ld rms_px=%.4f max_px=%.4f rms_deg=%.4f max_deg=%.4f false_tracking=%ld "
                  "tracking_without_truth=%ld\n",
                  n, n ? std::sqrt(sink.sum_px2 / n) : 0.0, sink.max_px, n ? std::sqrt(sink.sum_deg2 / n) : 0.0, sink.max_deg,
                  sink.false_tracking, sink.uncompared);
    }
    std::vector<double> compute_us;
    for (const std::int64_t ns : stats.roi_compute_ns) compute_us.push_back(ns * 1e-3);
    std::fprintf(report, "summary: frames=%llu tracked_share=%.4f compute_us_p50=%.1f compute_us_p99=%.1f compute_us_max=%.1f "
                "acquire_ms=%.2f\n",
                static_cast<unsigned long long>(stats.frames),
                stats.poses ? static_cast<double>(stats.tracked) / static_cast<double>(stats.poses) : 0.0,
                percentile(compute_us, 0.5), percentile(compute_us, 0.99),
                compute_us.empty() ? 0.0 : *std::max_element(compute_us.begin(), compute_us.end()),
                stats.search_compute_ns.empty() ? 0.0 : stats.search_compute_ns.front() * 1e-6);
    for (std::size_t t = 0; t < trackers.trackers.size(); ++t)
      session::print_detector_report(report, static_cast<int>(t), trackers.names[t], trackers.trackers[t]->detector_tau_status());
  };
  print_report(out_path == "-" ? stderr : stdout);
  // A report lost on stdout (a full disk, /dev/full) is said and repeated on stderr: exit 4.
  if (out_path != "-" && cli::report_lost("replay")) {
    print_report(stderr);
    return 4;
  }
  return 0;
}

}  // namespace

int sempose::cli::replay(int argc, char** argv) {
  try {
    return run_replay(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sempose replay: %s\n", cli::error_text(e).c_str());
    return 2;
  }
}
