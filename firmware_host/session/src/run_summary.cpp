#include "sempose/session/run_summary.hpp"

#include "sempose/hal/can_candump_log.hpp"

namespace sempose::session {

RunSummary collect_summary(const RunSetup& run, rt::HistogramSnapshot& e2e, double run_s,
                           std::uint64_t rt_allocs, std::uint64_t source_stalls) {
  RunSummary s;
  const pipeline::Pipeline& pipe = *run.pipeline;
  const auto& c = pipe.counters();
  std::uint64_t tracked = 0;
  for (int t = 0; t < pipe.target_count(); ++t) {
    s.poses += c.targets[static_cast<std::size_t>(t)].poses.get();
    tracked += c.targets[static_cast<std::size_t>(t)].tracked.get();
  }
  s.poses_per_s = run_s > 0 ? static_cast<double>(s.poses) / run_s : 0.0;
  s.tracked_share = s.poses ? static_cast<double>(tracked) / static_cast<double>(s.poses) : 0.0;
  s.dropped = pipe.dropped_frames();
  s.overruns = c.overruns.get();
  s.rt_allocs = rt_allocs;
  pipe.histograms().end_to_end.snapshot_into(e2e);
  if (e2e.count > 0) {
    s.e2e_us_p50 = e2e.percentile_us(0.5);
    s.e2e_us_p99 = e2e.percentile_us(0.99);
    s.e2e_us_p999 = e2e.percentile_us(0.999);
    s.e2e_us_max = e2e.max_ns / 1e3;
  }
  s.dwell_ns_min = c.dwell_min_ns.get();
  s.dwell_ns_max = c.dwell_max_ns.get();
  s.frames = c.frames_scanned.get();
  s.scan_errors = c.scan_errors.get();
  const auto& cc = run.can.sink->counters();
  s.can_sent = cc.poses_sent.load();
  s.can_dropped = cc.poses_dropped.load();
  s.can_bad_commands = cc.bad_commands.load();
  s.commands = c.commands.get();
  s.duration_s = run_s;
  s.can_bus_state = run.can.channel->detached() ? "detached" : hal::to_string(run.can.channel->bus_state());
  s.can_rebinds = run.can.channel->counters().rebinds.load();
  if (run.synced) {
    const auto& sc = run.synced->counters();
    s.frame_sync = true;
    s.sync = {sc.edges.load(), sc.missed.load(), sc.late.load(), sc.spurious.load()};
  }
  s.output_errors = run.output_write_errors();
  // Lines lost in writing and poses the writer fell too far behind to keep (its ring full).
  s.csv_lines_lost = run.csv ? run.csv->lost_lines() + run.csv->dropped() : 0;
  const auto* candump = dynamic_cast<const hal::CandumpLogChannel*>(run.can.channel.get());
  s.can_log_bytes_lost =
      candump ? candump->bytes_pending() + candump->bytes_lost_to_deleted_file() + candump->bytes_dropped_ring_full() : 0;
  s.commands_rejected = c.commands_rejected.get();
  s.command_overflows = cc.commands_overflowed.load();
  s.source_stalls = source_stalls;
  return s;
}

void print_summary(std::FILE* out, const RunSummary& s) {
  auto u = [](std::uint64_t v) { return static_cast<unsigned long long>(v); };
  std::fprintf(out, "summary: poses=%llu poses_per_s=%.1f tracked_share=%.3f dropped=%llu overruns=%llu rt_allocs=%llu",
               u(s.poses), s.poses_per_s, s.tracked_share, u(s.dropped), u(s.overruns), u(s.rt_allocs));
  std::fprintf(out, " e2e_us_p50=%.0f e2e_us_p99=%.0f e2e_us_p999=%.0f e2e_us_max=%.1f dwell_ns_min=%llu dwell_ns_max=%llu",
               s.e2e_us_p50, s.e2e_us_p99, s.e2e_us_p999, s.e2e_us_max, u(s.dwell_ns_min), u(s.dwell_ns_max));
  std::fprintf(out, " frames=%llu scan_errors=%llu can_sent=%llu can_dropped=%llu can_bad_commands=%llu commands=%llu",
               u(s.frames), u(s.scan_errors), u(s.can_sent), u(s.can_dropped), u(s.can_bad_commands), u(s.commands));
  std::fprintf(out, " duration_s=%.2f can_bus_state=%s", s.duration_s, s.can_bus_state.c_str());
  if (s.frame_sync) {
    std::fprintf(out, " sync_edges=%llu sync_missed=%llu sync_late=%llu sync_spurious=%llu", u(s.sync.edges),
                 u(s.sync.missed), u(s.sync.late), u(s.sync.spurious));
  }
  std::fprintf(out, " output_errors=%llu csv_lines_lost=%llu can_log_bytes_lost=%llu commands_rejected=%llu",
               u(s.output_errors), u(s.csv_lines_lost), u(s.can_log_bytes_lost), u(s.commands_rejected));
  std::fprintf(out, " command_overflows=%llu source_stalls=%llu can_rebinds=%llu stdout_lines_lost=%llu\n",
               u(s.command_overflows), u(s.source_stalls), u(s.can_rebinds), u(s.stdout_lines_lost));
}

}  // namespace sempose::session
