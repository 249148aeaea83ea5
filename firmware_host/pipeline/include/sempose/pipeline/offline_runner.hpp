// The offline runner: drives any ScanSource through the trackers into a PoseSink on the
// calling thread — no threads, no RT, no rings. `sempose replay` and tests use it. It follows
// the RT pipeline's rules for one frame in flight (what the pipeline does in lock step):
// targets scanned in pipeline.schedule order, and each frame through the same TrackingStep
// as the pipeline's correlation stage (clock, governor, next scan, pose record), so a replay
// of a recording writes the pipeline's CSV for it bit for bit.
#pragma once

#include <cstdint>
#include <vector>

#include "sempose/config/governor_config.hpp"
#include "sempose/config/pipeline_config.hpp"
#include "sempose/hal/frame.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/pipeline/pose_sink.hpp"
#include "sempose/pipeline/stage_clock.hpp"
#include "sempose/pipeline/tracking_step.hpp"
#include "sempose/rt/result.hpp"

namespace sempose::pose {
class Tracker;
}

namespace sempose::pipeline {

struct OfflineRunStats {
  std::uint64_t frames = 0;        // scans completed (good or flagged bad)
  std::uint64_t scan_errors = 0;   // refused starts, failed or lost scans
  std::uint64_t poses = 0;
  std::uint64_t tracked = 0;       // poses in state TRACKING
  std::uint64_t publish_failures = 0;  // poses the sink dropped or failed to write
  bool source_ended = false;
  // Wall time of each tracker update: ROI poses, and full-field start searches apart
  // (they are long by design and would hide the per-pose figure).
  std::vector<std::int64_t> roi_compute_ns;
  std::vector<std::int64_t> search_compute_ns;
};

class OfflineRunner {
 public:
  // Setup. trackers[i] tracks target i; source, trackers and sink must outlive the runner.
  // Returns a failure status from run() for impossible settings (no tracker, bad schedule).
  OfflineRunner(const config::PipelineConfig& pipeline, const config::GovernorConfig& governor,
                hal::ScanSource& source, std::vector<pose::Tracker*> trackers, PoseSink& sink,
                const StageClock& clock);

  // Scans and tracks until the source ends (a finite replay), max_frames scans were made
  // (0: no limit) or too many scans in a row failed. Time stamps come from the clock, as in
  // the pipeline (stage_clock.hpp).
  rt::Status run(std::uint64_t max_frames, OfflineRunStats& stats);

 private:
  config::PipelineConfig config_;
  const StageClock& clock_;
  hal::ScanSource& source_;
  std::vector<pose::Tracker*> trackers_;
  PoseSink& sink_;
  TrackingStep step_;
  std::vector<std::uint8_t> schedule_;
  hal::FramePool pool_;  // one slot: one frame in flight
};

}  // namespace sempose::pipeline
