// Counters and histograms the RT stages publish and the non-RT thread snapshots. Every
// counter has exactly one writing thread (relaxed load + store, no read-modify-write), so
// RT code never contends on a cache line with a lock prefix; readers see a recent value.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "sempose/hal/frame.hpp"
#include "sempose/rt/latency_histogram.hpp"
#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::pipeline {

// Single-writer counter.
class Counter {
 public:
  void add(std::uint64_t n = 1) noexcept { rt::add_single_writer(v_, n); }
  void set(std::uint64_t n) noexcept { v_.store(n, std::memory_order_relaxed); }
  std::uint64_t get() const noexcept { return v_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> v_{0};
};

struct TargetCounters {
  Counter poses;
  Counter tracked;   // poses in TRACKING state
  Counter searches;  // poses that ran the full-field start search
};

struct PipelineCounters {
  // acquisition
  Counter frames_scanned;
  Counter dropped_acquisition;  // finished frames replaced by a newer one while the ring was full
  Counter scan_errors;          // poll() kError or start() refused
  Counter no_free_slot;         // acquisition had to reuse a waiting frame's slot
  Counter dwell_min_ns;         // over all scans (set once the first scan started)
  Counter dwell_max_ns;
  Counter acquisition_allocs;   // heap calls made by the acquisition thread in its loop
  // correlation
  Counter dropped_correlation;  // older queued frames skipped to take the newest
  Counter overruns;             // a frame's scan ended before the previous pose was done
  Counter poses_ring_full;      // poses lost because output fell behind
  Counter commands;             // commands applied
  Counter commands_rejected;    // valid commands naming a pattern set or target that does not exist
  Counter correlation_allocs;
  // output
  Counter sent;
  Counter publish_dropped;
  Counter publish_errors;
  Counter output_allocs;
  std::array<TargetCounters, hal::kMaxTargets> targets;
};

// Histogram names in dump order.
struct PipelineHistograms {
  rt::LatencyHistogram poll_lag{"poll_lag"};      // scan end -> seen by the poller
  rt::LatencyHistogram queue{"queue"};            // seen -> correlation starts
  rt::LatencyHistogram compute{"compute"};        // correlation time per pose
  rt::LatencyHistogram output{"output"};          // pose done -> sent
  rt::LatencyHistogram end_to_end{"end_to_end"};  // scan end -> sent
  rt::LatencyHistogram scan_time{"scan_time"};    // scan start -> scan end (dwell × pixels + flyback)
  // The governor's dwell: recorded as dwell_ns µs, so the 1 µs buckets read as 1 ns.
  rt::LatencyHistogram dwell_ns{"dwell_ns"};
  // Cost of arming a scan: the time spent in ScanSource::start() (a Comedi card: the command
  // ioctls and the raster write; the simulator: rendering). Wall clock, also in virtual time.
  rt::LatencyHistogram arm{"arm"};

  std::vector<rt::HistogramSnapshot> snapshot() const {
    return {poll_lag.snapshot(), queue.snapshot(), compute.snapshot(), output.snapshot(),
            end_to_end.snapshot(), scan_time.snapshot(), dwell_ns.snapshot(), arm.snapshot()};
  }
  // Into snapshots made by snapshot() (same order): no allocation
  // (LatencyHistogram::snapshot_into).
  void snapshot_into(std::vector<rt::HistogramSnapshot>& s) const noexcept {
    const rt::LatencyHistogram* all[] = {&poll_lag,   &queue,     &compute,  &output,
                                         &end_to_end, &scan_time, &dwell_ns, &arm};
    for (std::size_t i = 0; i < s.size() && i < std::size(all); ++i) all[i]->snapshot_into(s[i]);
  }
};

}  // namespace sempose::pipeline
