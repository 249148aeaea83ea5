// The real-time pipeline (README: How it works): three stages on pinned SCHED_FIFO threads.
//
//   acquisition ──frame ring (slot indices)──▶ correlation ──pose ring──▶ output ──▶ PoseSink
//        ▲   └◀──────── free ring (slot indices) ───┘  │                     │
//        └──── per-target plan mailboxes (ROI + dwell) ┘   ◀── command ring ──┘
//
// - acquisition polls the ScanSource ISR-like and starts the next ROI scan the moment the
//   last one is done, following the target schedule (A, B, A, B … or configured); it never
//   waits for the tracker: with the frame ring full it keeps the newest finished frame aside
//   and drops the older one (counted).
// - correlation drains its ring to the newest frame (older ones are dropped and counted),
//   runs that target's tracker, feeds the governor, and publishes the target's next ROI and
//   dwell through a latest-value mailbox.
// - output publishes poses to the sink, services it (heartbeats, bus state) and forwards its
//   commands (pattern set, start, stop, re-acquire) to correlation through an SPSC ring. It
//   may run on the correlation thread (output_on_correlation_thread).
// Everything is allocated in the constructor; the loops are noexcept, lock-free and make no
// heap calls, no blocking syscalls other than clock_nanosleep (sleep polling), no I/O.
//
// Time stamps and pacing come from an injected StageClock (stage_clock.hpp): live
// (CLOCK_MONOTONIC) or virtual (tests, benchmarks, replay: lock step, modelled compute).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sempose/config/governor_config.hpp"
#include "sempose/config/pipeline_config.hpp"
#include "sempose/hal/frame.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/pipeline/pipeline_stats.hpp"
#include "sempose/pipeline/pose_sink.hpp"
#include "sempose/pipeline/stage_clock.hpp"
#include "sempose/pipeline/tracking_step.hpp"
#include "sempose/rt/mailbox.hpp"
#include "sempose/rt/result.hpp"
#include "sempose/rt/rt_thread.hpp"
#include "sempose/rt/spsc_ring.hpp"

namespace sempose::pose {
class Tracker;
}

namespace sempose::pipeline {

// Pixels one frame-pool slot holds: the full field (the start search scans it) or the
// largest ROI, whichever is more. Setup only.
inline std::size_t frame_slot_pixels(const hal::ScanLimits& l) noexcept {
  const auto field = static_cast<std::size_t>(l.field_w) * static_cast<std::size_t>(l.field_h);
  const auto roi = static_cast<std::size_t>(l.max_roi_w) * static_cast<std::size_t>(l.max_roi_h);
  return field > roi ? field : roi;
}

// What acquisition scans next for one target (latest value, from correlation). A trivial
// type (no member initializers): the mailbox copies it as raw words.
struct ScanPlan {
  std::int32_t x, y, w, h;  // the ROI
  std::uint32_t dwell_ns;
  std::uint32_t enabled;    // 0 after a stop command
};

// PipelineStatus's contents as a trivial type for the status mailbox.
struct StatusWords {
  std::uint32_t dwell_ns;
  std::uint8_t state;
  std::uint8_t pattern_set;
  std::uint8_t running;
  std::uint8_t last_command_seq;   // last command that took effect
  std::uint32_t commands_rejected; // valid commands naming nothing that exists
};

class Pipeline {
 public:
  static constexpr std::size_t kFrameRingCapacity = 16;
  static constexpr std::size_t kFreeRingCapacity = 64;
  static constexpr std::size_t kPoseRingCapacity = 256;
  static constexpr std::size_t kCommandRingCapacity = 16;
  static constexpr std::size_t kMaxSchedule = 16;

  // Setup (allocates the frame pool and histograms). trackers[i] tracks target i; sink and
  // clock must outlive the pipeline. Throws std::invalid_argument with a message on
  // impossible settings.
  Pipeline(const config::PipelineConfig& pipeline, const config::GovernorConfig& governor,
           hal::ScanSource& source, std::vector<pose::Tracker*> trackers, PoseSink& sink, const StageClock& clock);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  // The frame pool's slots and bytes for a config and a scan, before anything is allocated (a
  // setup checks them against the memory there is: up to 64 slots of a 16384² field is 32 GiB).
  static std::size_t frame_pool_slots_for(const config::PipelineConfig& pipeline) noexcept;
  static std::uint64_t frame_pool_bytes_for(const config::PipelineConfig& pipeline,
                                            const hal::ScanLimits& limits) noexcept;

  // Starts the stage threads. strict: refuse without SCHED_FIFO/affinity (else warn and run).
  rt::Status start(bool strict);
  // Stops scanning; the stages finish the frames in flight, then exit. Async-signal-safe.
  void request_stop() noexcept { stop_requested_.store(true, std::memory_order_release); }
  // Stop by itself after this many frames were scanned (tests, benchmarks); 0: never.
  void stop_after_frames(std::uint64_t n) noexcept { stop_after_frames_ = n; }
  // True once every stage has exited (after a stop request or the end of a finite source).
  bool finished() const noexcept { return output_done_.load(std::memory_order_acquire); }
  bool source_ended() const noexcept { return source_ended_.load(std::memory_order_acquire); }
  // Faults found outside the RT stages (the main thread's file writes, the source stall
  // watchdog, the service watchdog's stage-progress rule): set or cleared here, reported in
  // every heartbeat (PipelineStatus::fault_bits).
  void set_fault(std::uint8_t bits, bool on) noexcept {
    if (on) faults_.fetch_or(bits, std::memory_order_relaxed);
    else faults_.fetch_and(static_cast<std::uint8_t>(~bits), std::memory_order_relaxed);
  }
  std::uint8_t faults() const noexcept { return faults_.load(std::memory_order_relaxed); }
  // Set by the non-RT service watchdog (service::PipelineWatchdog) while a stage makes no progress.
  void report_stall(bool stalled) noexcept { set_fault(kFaultStageStalled, stalled); }
  // False after a STOP command (acquisition then idles on purpose: not a stall).
  bool scanning_enabled() const noexcept { return status_.read().running != 0; }
  void join();

  const PipelineCounters& counters() const noexcept { return counters_; }
  const PipelineHistograms& histograms() const noexcept { return histograms_; }
  // "acquisition: SCHED_FIFO 60 on CPU 1" etc., and the degradation warnings.
  std::vector<std::string> placements() const;
  std::vector<std::string> warnings() const;
  std::size_t frame_pool_bytes() const noexcept;
  int target_count() const noexcept { return static_cast<int>(trackers_.size()); }
  std::uint64_t dropped_frames() const noexcept {
    return counters_.dropped_acquisition.get() + counters_.dropped_correlation.get();
  }

 private:
  static constexpr rt::SlotOwner kAcq = rt::stage_owner(0);
  static constexpr rt::SlotOwner kCorr = rt::stage_owner(1);

  void acquisition_loop() noexcept;
  void correlation_loop() noexcept;
  void output_loop() noexcept;
  // One output cycle; returns true when it did any work.
  bool output_step() noexcept;
  void correlate(hal::FramePool::Index slot) noexcept;
  // Applies a command; false (and nothing changed) when it names a pattern set or target that
  // does not exist.
  bool apply_command(const Command& c) noexcept;
  void publish_plan(std::uint8_t target, bool enabled) noexcept;
  void idle_wait(std::int64_t until_ns) const noexcept;
  std::int64_t idle_sleep_ns() const noexcept;  // pipeline.idle_sleep_us in ns
  // The deadline of a whole idle sleep (pipeline.idle_sleep_us from now): what a stage that
  // waits on another stage sleeps, so that on a shared core the other stage gets to run.
  std::int64_t whole_idle_sleep() const noexcept;
  // A frame this late means a starved acquisition rather than a slow scan: correlation stops
  // polling every 5 us for it (see correlation_loop).
  static constexpr std::int64_t kOverdueBackoffNs = 250'000'000;

  config::PipelineConfig config_;
  const StageClock& clock_;
  hal::ScanSource& source_;
  std::vector<pose::Tracker*> trackers_;
  PoseSink& sink_;
  TrackingStep step_;  // correlation-owned (publish_plan also runs in the constructor)
  bool spin_;           // spin-poll (a live clock and polling: spin)
  bool sleep_polling_;  // sleep until a scan is due (a live clock and polling: sleep)
  std::uint32_t frame_ring_depth_;
  std::uint32_t pose_ring_depth_;
  std::array<std::uint8_t, kMaxSchedule> schedule_{};
  std::size_t schedule_len_ = 0;

  hal::FramePool pool_;
  rt::SpscRing<hal::FramePool::Index, kFrameRingCapacity> frames_;      // acquisition -> correlation
  rt::SpscRing<hal::FramePool::Index, kFreeRingCapacity> free_slots_;   // correlation -> acquisition
  rt::SpscRing<PoseRecord, kPoseRingCapacity> poses_;                   // correlation -> output
  rt::SpscRing<Command, kCommandRingCapacity> commands_;                // output -> correlation
  std::array<rt::Mailbox<ScanPlan>, hal::kMaxTargets> plans_;

  // Correlation-owned state.
  bool running_ = true;  // false after a stop command
  bool prev_pose_was_search_ = true;
  std::array<pose::TrackState, hal::kMaxTargets> last_state_{};
  // nm/px commanded with SELECT_PATTERN_SET (0: the pattern set's configured scale).
  std::array<double, hal::kMaxTargets> nm_per_px_override_{};
  // Acquisition only: the plan version of each target's last full-field scan (0: none).
  std::array<std::uint32_t, hal::kMaxTargets> full_field_version_{};
  rt::Mailbox<StatusWords> status_;  // correlation -> output (heartbeat contents)
  std::int64_t last_pose_done_ns_ = 0;  // output-owned: "now" for service() on a virtual clock

  PipelineCounters counters_;
  PipelineHistograms histograms_;

  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> source_ended_{false};
  std::atomic<std::uint8_t> faults_{0};
  std::atomic<bool> acquisition_done_{false};
  std::atomic<bool> correlation_done_{false};
  std::atomic<bool> output_done_{false};
  std::atomic<std::uint64_t> frames_handed_{0};    // acquisition -> correlation (virtual pacing)
  std::atomic<std::uint64_t> frames_taken_{0};
  std::atomic<std::int64_t> next_frame_expected_ns_{0};  // for the correlation's idle sleep
  std::uint64_t stop_after_frames_ = 0;

  rt::RtThread acquisition_thread_;
  rt::RtThread correlation_thread_;
  rt::RtThread output_thread_;
};

}  // namespace sempose::pipeline
