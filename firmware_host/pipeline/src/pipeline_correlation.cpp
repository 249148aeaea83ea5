// The correlation stage (pipeline.hpp): applies commands, tracks the newest frame, feeds the
// governor, plans the target's next scan and queues the pose for output.
#include <algorithm>

#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pose/tracker.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {

bool Pipeline::apply_command(const Command& c) noexcept {
  const std::size_t n = trackers_.size();
  // A command naming something that does not exist is refused as a whole (and not
  // acknowledged): a controller must not believe a magnification step or target changed.
  const bool target_ok = c.target == 0xFF || c.target < n;
  bool ok = target_ok;
  if (ok && c.kind == CommandKind::kSelectPatternSet) {
    for (std::size_t t = 0; t < n; ++t) {
      // A set that does not exist, or an nm/px at which its target is beyond the tracked scales.
      if ((c.target == 0xFF || c.target == t) && !trackers_[t]->selectable(c.arg, c.nm_per_px)) ok = false;
    }
  }
  StatusWords st = status_.read();
  if (!ok) {
    counters_.commands_rejected.add();
    st.commands_rejected = static_cast<std::uint32_t>(counters_.commands_rejected.get());
    status_.publish(st);
    return false;
  }
  auto for_targets = [&](auto&& fn) {
    for (std::size_t t = 0; t < n; ++t) {
      if (c.target == 0xFF || c.target == t) fn(static_cast<std::uint8_t>(t));
    }
  };
  switch (c.kind) {
    case CommandKind::kSelectPatternSet:
      // A non-zero scale from the controller overrides the configured nm/px of the set
      // (e.g. a magnification step calibrated on the microscope); 0 keeps the configured one.
      // The tracker takes it as the target's expected size (set's nm/px over this one).
      for_targets([&](std::uint8_t t) {
        if (trackers_[t]->select_pattern_set(c.arg, c.nm_per_px)) nm_per_px_override_[t] = c.nm_per_px > 0 ? c.nm_per_px : 0;
      });
      break;
    case CommandKind::kStart:
      running_ = true;
      break;
    case CommandKind::kStop:
      running_ = false;
      break;
    case CommandKind::kReacquire:
      for_targets([&](std::uint8_t t) { trackers_[t]->request_reacquire(); });
      break;
  }
  for (std::size_t t = 0; t < n; ++t) publish_plan(static_cast<std::uint8_t>(t), running_);
  st.running = running_ ? 1 : 0;
  st.last_command_seq = c.seq;
  status_.publish(st);
  counters_.commands.add();
  return true;
}

void Pipeline::correlate(hal::FramePool::Index slot) noexcept {
  hal::FrameSlot& s = pool_[slot];
  hal::FrameMeta& m = s.meta;
  const TrackingStep::Outcome o = step_.track(m, s.pixels);
  const pose::PoseEstimate& est = o.est;
  const std::uint8_t target = o.target;

  // The frame waited for the tracker: a deadline overrun (not counted after a start search,
  // which is long by design).
  if (o.prev_pose_done_ns != 0 && m.t_scan_end_ns < o.prev_pose_done_ns && !prev_pose_was_search_) {
    counters_.overruns.add();
  }
  prev_pose_was_search_ = est.searched;
  histograms_.queue.record_ns(o.t_start_ns - m.t_seen_ns);
  histograms_.compute.record_ns(o.compute_ns);

  const bool tracking = est.state == pose::TrackState::kTracking;
  publish_plan(target, running_);
  last_state_[target] = est.state;
  {
    StatusWords st = status_.read();  // keeps the command acknowledgement fields
    // Worst first: LOST, ACQUIRING, UNCERTAIN (followed, pose not trusted), TRACKING.
    auto rank = [](pose::TrackState ts) { return ts == pose::TrackState::kUncertain ? 1 : 2 * static_cast<int>(ts); };
    pose::TrackState worst = pose::TrackState::kTracking;
    for (std::size_t t = 0; t < trackers_.size(); ++t) {
      if (rank(last_state_[t]) > rank(worst)) worst = last_state_[t];
    }
    st.state = static_cast<std::uint8_t>(worst);
    st.pattern_set = est.pattern_set;
    st.running = running_ ? 1 : 0;
    st.dwell_ns = m.dwell_ns;
    status_.publish(st);
  }

  TargetCounters& tc = counters_.targets[target];
  tc.poses.add();
  if (tracking) tc.tracked.add();
  if (est.searched) tc.searches.add();

  const double nm_per_px =
      nm_per_px_override_[target] > 0 ? nm_per_px_override_[target] : trackers_[target]->nm_per_px();
  const PoseRecord p = step_.record(m, o, nm_per_px);
  if (poses_.size() >= pose_ring_depth_ || !poses_.try_push(p)) counters_.poses_ring_full.add();
}

void Pipeline::correlation_loop() noexcept {
  const std::uint64_t allocs_at_start = rt::alloc::this_thread_allocations();
  const bool run_output = config_.output_on_correlation_thread;
  const std::int64_t slack_ns = static_cast<std::int64_t>(config_.poll_slack_us) * rt::kNsPerUs;
  for (;;) {
    Command c;
    while (commands_.try_pop(c)) apply_command(c);

    // Drain to the newest frame: older ones are stale by now (dropped, counted).
    hal::FramePool::Index newest = 0;
    bool have = false;
    hal::FramePool::Index i = 0;
    std::uint64_t taken = 0;
    while (frames_.try_pop(i)) {
      ++taken;
      if (have) {
        pool_.transfer(newest, kCorr, kAcq);
        free_slots_.try_push(newest);
        counters_.dropped_correlation.add();
      }
      newest = i;
      have = true;
    }
    if (have) {
      correlate(newest);
      pool_.transfer(newest, kCorr, kAcq);
      free_slots_.try_push(newest);
      // Virtual pacing: count the frame as taken only once its pose exists.
      frames_taken_.store(frames_taken_.load(std::memory_order_relaxed) + taken, std::memory_order_release);
      if (run_output) output_step();
      continue;
    }
    if (run_output && output_step()) continue;
    if (acquisition_done_.load(std::memory_order_acquire) && frames_.empty()) break;
    // Wait for the frame due next. While the non-RT watchdog reports a stall, or once the
    // frame is kOverdueBackoffNs late (the acquisition is starved: the watchdog is about to
    // say so), poll every idle_sleep_us instead of every 5 us, so this FIFO thread does not
    // starve the non-RT thread on its core, which must declare the stall and answer SIGTERM
    // (polling every 5 us delayed the stall report by 1-1.6 s). (Backing off on lateness of
    // > 1 ms or > 50 ms changed which frame a REACQUIRE met in the VM test.)
    const std::int64_t due = next_frame_expected_ns_.load(std::memory_order_relaxed) + slack_ns;
    const std::int64_t now = rt::now_ns();
    const bool backoff = (faults_.load(std::memory_order_relaxed) & kFaultStageStalled) != 0 ||
                         (due > 0 && now - due > kOverdueBackoffNs);
    idle_wait(backoff ? whole_idle_sleep() : due);
  }
  if (run_output) {
    while (output_step()) {
    }
  }
  counters_.correlation_allocs.set(rt::alloc::this_thread_allocations() - allocs_at_start);
  correlation_done_.store(true, std::memory_order_release);
  if (run_output) output_done_.store(true, std::memory_order_release);
}

}  // namespace sempose::pipeline
