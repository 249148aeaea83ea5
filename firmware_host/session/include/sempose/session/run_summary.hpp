// The machine-readable last line of `sempose run` (README: Commands): every figure as a named
// field, filled from the finished run (collect) and printed in the documented order (print).
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

#include "sempose/session/run_setup.hpp"

namespace sempose::session {

struct SyncEdgeCounts {
  std::uint64_t edges = 0, missed = 0, late = 0, spurious = 0;
};

struct RunSummary {
  std::uint64_t poses = 0;
  double poses_per_s = 0;
  double tracked_share = 0;
  std::uint64_t dropped = 0;
  std::uint64_t overruns = 0;
  std::uint64_t rt_allocs = 0;
  double e2e_us_p50 = 0, e2e_us_p99 = 0, e2e_us_p999 = 0, e2e_us_max = 0;
  std::uint64_t dwell_ns_min = 0, dwell_ns_max = 0;
  std::uint64_t frames = 0;
  std::uint64_t scan_errors = 0;
  std::uint64_t can_sent = 0, can_dropped = 0, can_bad_commands = 0;
  std::uint64_t commands = 0;
  double duration_s = 0;
  std::string can_bus_state;      // error-active / error-passive / bus-off, or detached (interface gone)
  std::uint64_t can_rebinds = 0;  // times the CAN interface came back and was bound again
  bool frame_sync = false;  // the sync_* fields are printed only with GPIO frame sync
  SyncEdgeCounts sync;
  std::uint64_t output_errors = 0;
  std::uint64_t csv_lines_lost = 0;
  std::uint64_t can_log_bytes_lost = 0;
  std::uint64_t commands_rejected = 0;
  std::uint64_t command_overflows = 0;
  std::uint64_t source_stalls = 0;
  std::uint64_t stdout_lines_lost = 0;  // status lines a blocked or closed stdout did not take
};

// From a finished run (stages joined, sinks closed): run_s the run's length, rt_allocs the
// heap calls on RT threads, source_stalls the stall watchdog's count. `e2e` is a snapshot of the
// end-to-end histogram made at setup, refreshed here without allocating.
RunSummary collect_summary(const RunSetup& run, rt::HistogramSnapshot& e2e, double run_s,
                           std::uint64_t rt_allocs, std::uint64_t source_stalls);
// "summary: poses=… source_stalls=…\n".
void print_summary(std::FILE* out, const RunSummary& s);

}  // namespace sempose::session
