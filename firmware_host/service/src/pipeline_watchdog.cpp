#include "sempose/service/pipeline_watchdog.hpp"

#include <algorithm>
#include <string>

#include "sempose/pipeline/pipeline.hpp"

namespace sempose::service {

PipelineWatchdog::PipelineWatchdog(pipeline::Pipeline& pipe, SystemdNotifier& notifier, std::int64_t stall_timeout_ns,
                                   std::int64_t now_ns, std::FILE* log)
    : pipe_(pipe),
      notifier_(notifier),
      monitor_(stall_timeout_ns, now_ns),
      ping_period_ns_(notifier.watchdog_interval_ns() / 2),
      sample_period_ns_(std::max<std::int64_t>(1'000'000, stall_timeout_ns / 4)),
      next_ping_ns_(now_ns),
      next_due_ns_(now_ns),
      log_(log) {
  if (ping_period_ns_ > 0) sample_period_ns_ = std::min(sample_period_ns_, ping_period_ns_ / 2);
}

void PipelineWatchdog::poll(std::int64_t now_ns) {
  const auto& c = pipe_.counters();
  StageCounts counts;
  counts.frames = c.frames_scanned.get();
  for (int t = 0; t < pipe_.target_count(); ++t) counts.poses += c.targets[static_cast<std::size_t>(t)].poses.get();
  counts.published = c.sent.get() + c.publish_dropped.get() + c.publish_errors.get();
  const std::uint8_t stalled = monitor_.update(now_ns, counts, pipe_.scanning_enabled());
  pipe_.report_stall(stalled != 0);

  if (stalled != reported_) {
    if (stalled != 0) {
      const std::string what = describe_stall(stalled, monitor_, now_ns);
      std::fprintf(log_, "watchdog: stalled: %s; %s\n", what.c_str(),
                   ping_period_ns_ > 0 ? "systemd watchdog no longer fed" : "no systemd watchdog configured");
      notifier_.status("stalled: " + what);
    } else {
      std::fprintf(log_, "watchdog: every stage progressing again\n");
      notifier_.status("running");
    }
    std::fflush(log_);
    reported_ = stalled;
  }
  if (ping_period_ns_ > 0 && stalled == 0 && now_ns >= next_ping_ns_) {
    // A ping that does not reach systemd (the notify socket gone) is said once when it starts and
    // once when pings arrive again, and counted: they failed unsaid and the run ended with a clean
    // summary while systemd would have stopped it (hostile round 9).
    const bool sent = notifier_.watchdog();
    if (sent) {
      ++pings_;
    } else {
      ++ping_failures_;
    }
    if (sent == ping_failing_) {
      std::fprintf(log_, sent ? "watchdog: WATCHDOG=1 reaches systemd again\n"
                              : "watchdog: WATCHDOG=1 could not be sent to NOTIFY_SOCKET: systemd will stop this run "
                                "after WatchdogSec\n");
      std::fflush(log_);
      ping_failing_ = !sent;
    }
    next_ping_ns_ = now_ns + ping_period_ns_;
  }
  next_due_ns_ = now_ns + sample_period_ns_;
}

}  // namespace sempose::service
