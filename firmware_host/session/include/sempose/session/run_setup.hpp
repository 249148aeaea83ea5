// Everything `sempose run` builds before its stages start, in two phases so a stop signal or
// a bad input between them leaves no output file behind:
//   build_inputs   scan source (+ GPIO frame sync), trackers, stage clock — reads files only;
//   build_outputs  output folders, CAN channel and sink, GPIO outputs, CSV sink, the sink
//                  chain (GPIO ← tee(CAN, CSV)) and the pipeline — creates the outputs, and
//                  ignores SIGPIPE (a closed stdout is an EPIPE, not the end of the run).
// Allocates; never on an RT thread. Errors name the section and the problem.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "sempose/can_output/factory.hpp"
#include "sempose/can_output/gpio_pose_sink.hpp"
#include "sempose/config/app_config.hpp"
#include "sempose/hal/gpio_synced_source.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/pipeline/csv_pose_sink.hpp"
#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pipeline/stage_clock.hpp"
#include "sempose/pipeline/tracker_setup.hpp"
#include "sempose/rt/result.hpp"
#include "sempose/session/made_folders.hpp"

namespace sempose::session {

// An exclusive advisory lock (flock) on an output file for as long as the run writes it. Two
// `sempose run` (or a run and a replay) on one CSV or candump log used to write into the same
// file: the second truncated the first's lines, then both interleaved theirs. Setup only.
class OutputLock {
 public:
  OutputLock() = default;
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;
  OutputLock(OutputLock&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }
  OutputLock& operator=(OutputLock&&) = delete;

  // `what` names the file in the message (a config key or an option). A regular file (or a
  // missing one, created here without truncating anything) is locked; a device (/dev/null,
  // /dev/full) or "-" is not. Fails naming `what` when another process holds the lock.
  rt::Status acquire(const std::string& what, const std::string& path);
  // The same for a folder the run writes fixed file names into (the histograms), made when
  // missing: two runs on one folder renamed each other's files away, each saying it wrote its
  // own (found probing).
  rt::Status acquire_folder(const std::string& what, const std::string& path);
  // Empties the locked file (opened without truncating: the run empties its outputs once every
  // one of them has opened); true when emptied or nothing is locked (a device, "-").
  bool empty_file() const noexcept;

 private:
  // Takes the exclusive lock on the opened fd and keeps it (closes it when refused).
  rt::Status hold(int fd, const std::string& what, const std::string& path, const std::string& writers_clash);
  int fd_ = -1;
};

struct RunSetup {
  // Inputs.
  std::unique_ptr<hal::ScanSource> source;
  std::unique_ptr<hal::GpioFrameSync> frame_sync;
  std::unique_ptr<hal::GpioSyncedSource> synced;  // source behind the frame-sync edge, or null
  hal::ScanSource* scan = nullptr;                // what the pipeline scans: synced or source
  pipeline::TrackerSetup trackers;
  std::unique_ptr<pipeline::StageClock> clock;
  // Outputs.
  can_output::CanOutput can;
  std::unique_ptr<hal::GpioOutputs> gpio_out;
  std::unique_ptr<pipeline::CsvPoseSink> csv;   // output.poses_csv, or null
  std::unique_ptr<pipeline::TeePoseSink> tee;
  std::unique_ptr<can_output::GpioPoseSink> gpio_sink;
  std::vector<OutputLock> output_locks;         // the CSV's, the candump log's and the histogram folder's, held to the end
  MadeFolders made_folders;                     // the outputs' folders build_outputs made (removed when it refuses the run)
  pipeline::PoseSink* sink = nullptr;           // the head of the chain the pipeline publishes to
  std::vector<std::string> output_notes;        // what setup did to the outputs (output.keep_previous), for the log
  std::unique_ptr<pipeline::Pipeline> pipeline;

  // Failed writes of the file outputs so far (CSV, candump log).
  std::uint64_t output_write_errors() const;
  int last_output_errno() const;
  // Whether the CSV's or the candump log's ring overflowed between two flushes (poses or lines
  // dropped, counted in csv_lines_lost / can_log_bytes_lost): output.csv_buffer_poses or
  // can.log_buffer_bytes too small for what comes in 50 ms.
  bool output_ring_overflowed() const;
  // Writes what the file sinks hold (non-RT; every wake of the main loop and shutdown).
  void flush_outputs();
};

rt::Status build_inputs(const config::AppConfig& cfg, RunSetup& out);
// What `sempose replay` tracks: cfg with the recording in frames_dir as its scan source, on
// the virtual clock, played once, without a GPIO frame sync (offline there is no scan
// generator) — the inputs `sempose run` would build for the same recording.
config::AppConfig replay_config(const config::AppConfig& cfg, const std::string& frames_dir);
// can_log_override: `--can-log FILE` (empty: the config's CAN output); hist_dir: the folder the
// histograms go to (--hist-dir or output.hist_dir; empty: none), locked like the files.
rt::Status build_outputs(const config::AppConfig& cfg, const std::string& can_log_override, const std::string& hist_dir,
                         RunSetup& out);

}  // namespace sempose::session
