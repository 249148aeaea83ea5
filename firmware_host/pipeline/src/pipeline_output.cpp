// The output stage (pipeline.hpp): publishes poses to the sink, services it (heartbeats, bus
// state) and forwards its commands to correlation.
#include "sempose/pipeline/pipeline.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {

bool Pipeline::output_step() noexcept {
  bool worked = false;
  PoseRecord p;
  while (poses_.try_pop(p)) {
    worked = true;
    const std::int64_t t_sent = clock_.output_now_ns(p.t_pose_done_ns);
    const PublishResult r = sink_.publish(p, t_sent);
    if (r == PublishResult::kSent) {
      counters_.sent.add();
    } else if (r == PublishResult::kDropped) {
      counters_.publish_dropped.add();
    } else {
      counters_.publish_errors.add();
    }
    histograms_.output.record_ns(t_sent - p.t_pose_done_ns);
    histograms_.end_to_end.record_ns(t_sent - p.t_scan_end_ns);
  }
  const StatusWords words = status_.read();
  PipelineStatus status;
  status.state = static_cast<pose::TrackState>(words.state);
  status.pattern_set = words.pattern_set;
  status.running = words.running != 0;
  status.dwell_ns = words.dwell_ns;
  status.dropped_frames = static_cast<std::uint32_t>(dropped_frames());
  status.overruns = static_cast<std::uint32_t>(counters_.overruns.get());
  status.last_command_seq = words.last_command_seq;
  status.commands_rejected = words.commands_rejected;
  status.fault_bits = faults_.load(std::memory_order_relaxed);
  // A stalled source produces no poses: the last pose's TRACKING must not stand for "valid".
  if (status.fault_bits & (kFaultSourceStalled | kFaultStageStalled)) status.state = pose::TrackState::kLost;
  if (worked) last_pose_done_ns_ = p.t_pose_done_ns;
  sink_.service(status, clock_.output_now_ns(last_pose_done_ns_));
  Command c;
  // Only take a command when there is room for it: the sink keeps the rest.
  while (commands_.size() < kCommandRingCapacity && sink_.next_command(c)) {
    worked = true;
    commands_.try_push(c);
  }
  return worked;
}

void Pipeline::output_loop() noexcept {
  const std::uint64_t allocs_at_start = rt::alloc::this_thread_allocations();
  for (;;) {
    if (output_step()) continue;
    if (correlation_done_.load(std::memory_order_acquire) && poses_.empty()) break;
    idle_wait(whole_idle_sleep());
  }
  counters_.output_allocs.set(rt::alloc::this_thread_allocations() - allocs_at_start);
  output_done_.store(true, std::memory_order_release);
}


}  // namespace sempose::pipeline
