// The hook `sempose run` calls from its non-RT loop: samples the pipeline's stage counters,
// feeds the systemd watchdog (WATCHDOG=1 every half WatchdogSec) only while no stage is
// stalled, and tells the pipeline about a stall so the CAN heartbeat carries it (bit
// `stalled`). A stalled pipeline therefore stops the pings and systemd restarts the service
// after WatchdogSec, while the bus already sees the fault. Prints one line when a stall
// starts and one when progress resumes.
#pragma once

#include <cstdint>
#include <cstdio>

#include "sempose/service/stage_progress.hpp"
#include "sempose/service/systemd_notify.hpp"

namespace sempose::pipeline {
class Pipeline;
}

namespace sempose::service {

class PipelineWatchdog {
 public:
  PipelineWatchdog(pipeline::Pipeline& pipe, SystemdNotifier& notifier, std::int64_t stall_timeout_ns,
                   std::int64_t now_ns, std::FILE* log = stdout);
  // Call often (at least every quarter of the stall timeout and of WatchdogSec).
  void poll(std::int64_t now_ns);
  // Latest time poll() should run again (for the caller's wait timeout).
  std::int64_t next_due_ns() const noexcept { return next_due_ns_; }
  std::uint8_t stalled() const noexcept { return monitor_.stalled(); }
  std::uint64_t pings() const noexcept { return pings_; }
  std::uint64_t ping_failures() const noexcept { return ping_failures_; }  // WATCHDOG=1 not sent

 private:
  pipeline::Pipeline& pipe_;
  SystemdNotifier& notifier_;
  ProgressMonitor monitor_;
  std::int64_t ping_period_ns_;   // half of WatchdogSec (0: no watchdog)
  std::int64_t sample_period_ns_;
  std::int64_t next_ping_ns_;
  std::int64_t next_due_ns_;
  std::FILE* log_;
  std::uint8_t reported_ = 0;
  std::uint64_t pings_ = 0;
  std::uint64_t ping_failures_ = 0;
  bool ping_failing_ = false;  // the last ping failed (said once per change)
};

}  // namespace sempose::service
