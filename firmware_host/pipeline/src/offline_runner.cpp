#include "sempose/pipeline/offline_runner.hpp"

#include <algorithm>
#include <string>

#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pose/tracker.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {
namespace {

// A source that refuses or loses this many scans in a row will not recover by retrying.
constexpr int kMaxConsecutiveScanErrors = 100;

}  // namespace

OfflineRunner::OfflineRunner(const config::PipelineConfig& pipeline, const config::GovernorConfig& governor,
                             hal::ScanSource& source, std::vector<pose::Tracker*> trackers, PoseSink& sink,
                             const StageClock& clock)
    : config_(pipeline),
      clock_(clock),
      source_(source),
      trackers_(std::move(trackers)),
      sink_(sink),
      step_(governor, source.limits(), trackers_, clock),
      pool_(1, frame_slot_pixels(source.limits())) {
  for (int t : pipeline.schedule) {
    if (t >= 0 && t < static_cast<int>(trackers_.size())) schedule_.push_back(static_cast<std::uint8_t>(t));
  }
  if (schedule_.empty()) {
    for (std::size_t t = 0; t < trackers_.size(); ++t) schedule_.push_back(static_cast<std::uint8_t>(t));
  }
}

rt::Status OfflineRunner::run(std::uint64_t max_frames, OfflineRunStats& stats) {
  if (trackers_.empty() || trackers_.size() > static_cast<std::size_t>(hal::kMaxTargets) ||
      std::find(trackers_.begin(), trackers_.end(), nullptr) != trackers_.end()) {
    return rt::Status::failure("offline runner: 1 to " + std::to_string(hal::kMaxTargets) + " targets with a tracker each");
  }
  if (schedule_.size() != (config_.schedule.empty() ? trackers_.size() : config_.schedule.size())) {
    return rt::Status::failure("pipeline.schedule: an entry is not a target index");
  }
  hal::FrameSlot& slot = pool_[0];
  int consecutive_errors = 0;
  // Each target's next scan, planned right after its last pose as the pipeline's correlation
  // stage does (the governor's state then matches the pipeline's at every decision).
  std::vector<hal::ScanRequest> plans(trackers_.size());
  for (std::size_t t = 0; t < trackers_.size(); ++t) plans[t] = step_.next_scan(static_cast<std::uint8_t>(t));
  for (std::size_t schedule_pos = 0; max_frames == 0 || stats.frames < max_frames;
       schedule_pos = (schedule_pos + 1) % schedule_.size()) {
    if (consecutive_errors >= kMaxConsecutiveScanErrors) {
      return rt::Status::failure("scan source: " + std::to_string(consecutive_errors) + " scans in a row failed");
    }
    const std::uint8_t target = schedule_[schedule_pos];
    const hal::StartResult started = source_.start(plans[target], slot);
    if (started == hal::StartResult::kEnded) {
      stats.source_ended = true;
      break;
    }
    if (started != hal::StartResult::kStarted) {
      ++stats.scan_errors;
      ++consecutive_errors;
      continue;
    }
    hal::PollResult polled = source_.poll();
    while (polled == hal::PollResult::kBusy) {
      // A live clock: sleep until the scan is due, then check again (no RT here).
      const std::int64_t due = source_.expected_done_ns();
      rt::sleep_until_ns(std::max(due, rt::now_ns() + 10 * rt::kNsPerUs));
      polled = source_.poll();
    }
    if (polled == hal::PollResult::kIdle) {  // the source lost the scan
      ++stats.scan_errors;
      ++consecutive_errors;
      continue;
    }
    hal::FrameMeta& m = slot.meta;
    if (polled == hal::PollResult::kError) {
      m.status = hal::FrameStatus::kBad;  // tracked all the same: the tracker reports the bad frame
      ++stats.scan_errors;
    } else {
      consecutive_errors = 0;
    }
    ++stats.frames;
    m.t_seen_ns = clock_.seen_ns(m.t_scan_end_ns);

    const std::int64_t wall0 = rt::now_ns();
    const TrackingStep::Outcome o = step_.track(m, slot.pixels);
    (o.est.searched ? stats.search_compute_ns : stats.roi_compute_ns).push_back(rt::now_ns() - wall0);
    trackers_[o.target]->maintain_appearance();  // offline: the appearance rebuild runs between frames (not timed)
    plans[o.target] = step_.next_scan(o.target);

    const PoseRecord p = step_.record(m, o, trackers_[o.target]->nm_per_px());
    if (sink_.publish(p, clock_.output_now_ns(p.t_pose_done_ns)) != PublishResult::kSent) ++stats.publish_failures;
    sink_.flush();  // off the RT path: write every pose at once, so no sink ring can overflow
    ++stats.poses;
    if (o.est.state == pose::TrackState::kTracking) ++stats.tracked;
  }
  return rt::Status::success();
}

}  // namespace sempose::pipeline
