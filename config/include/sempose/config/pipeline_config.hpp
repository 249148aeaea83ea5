// Settings of the real-time pipeline (threads, cores, priorities, polling, ring and pool
// sizes, target schedule) and of the run's outputs (files, histogram dumps).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sempose/config/reader.hpp"

namespace sempose::config {

// One RT stage's thread.
struct StageThreadConfig {
  int cpu = -1;       // -1: not pinned
  int priority = 0;   // SCHED_FIFO 1..99; 0: SCHED_OTHER (development)
};

struct PipelineConfig {
  // sleep: clock_nanosleep until the scan's expected end (minus poll_slack_us), then poll;
  //        idle stages sleep idle_sleep_us (development machines, shared cores).
  // spin:  busy-poll (a dedicated isolated core per stage; production).
  std::string polling = "sleep";
  std::uint32_t poll_slack_us = 20;
  std::uint32_t idle_sleep_us = 100;
  bool strict_rt = false;        // refuse to start without SCHED_FIFO/affinity/mlock
  bool lock_memory = true;       // mlockall + no mmap/trim (rt::lock_process_memory)
  bool hold_dma_latency = true;  // /dev/cpu_dma_latency = 0 while running
  StageThreadConfig acquisition{1, 60};
  StageThreadConfig correlation{1, 50};
  StageThreadConfig output{1, 40};
  bool output_on_correlation_thread = true;  // output runs after each pose on the correlation thread
  int non_rt_cpu = 0;            // main thread (signals, dumps, flushes); -1: not pinned
  std::uint32_t frame_ring = 4;  // frames queued between acquisition and correlation (<= 16)
  std::uint32_t pose_ring = 64;  // poses queued between correlation and output (<= 256)
  std::uint32_t frame_pool_slots = 8;  // >= frame_ring + 3 (scanning, correlating, spare)
  std::vector<int> schedule;     // ROI order by target index, e.g. [0, 0, 1]; empty: 0, 1, 0, 1 ...
  // Virtual-time sources only: modelled compute time per pose (0: measured CPU time).
  std::uint32_t virtual_compute_ns = 0;
  std::uint32_t stats_period_ms = 1000;  // non-RT thread: sink flush / status print period
};

struct OutputConfig {
  std::string poses_csv;          // "" = no CSV (CAN only, once the CAN sink exists)
  std::string hist_dir;           // "" = no histogram dump at exit (overridden by --hist-dir)
  std::uint32_t csv_buffer_poses = 65536;  // RT-side ring of poses waiting for the CSV writer
  bool print_status = true;       // one status line per stats period on stdout
  // Each start keeps the last run's poses CSV and candump log as NAME.1 before emptying them: a
  // restarted service (a watchdog kill, a crash) no longer erases the record of the run that failed.
  bool keep_previous = false;
};

// Reads `pipeline:` (config/src/pipeline_section.cpp).
void read_pipeline(Section& section, PipelineConfig& out);
// Reads `output:` (config/src/pipeline_section.cpp).
void read_output(Section& section, OutputConfig& out);

}  // namespace sempose::config
