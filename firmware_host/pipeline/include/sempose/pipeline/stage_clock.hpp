// How the stages tell time and pace themselves — the one place virtual time lives, injected
// into the RT pipeline and the offline runner (scan sources know nothing of it).
//
// - LiveStageClock: CLOCK_MONOTONIC. A frame is seen when acquisition sees it, a pose is done
//   when the tracker returns, sent when the sink is called; acquisition never waits for
//   correlation (a slow consumer costs frames, counted).
// - VirtualStageClock: the scan source's deterministic clock (simulator, replay on
//   `clock: virtual`). Seen = scan end; pose done = max(seen, previous pose done) + compute,
//   compute = the modelled time (pipeline.virtual_compute_ns) or the measured one when 0;
//   sent = pose done; and acquisition runs in lock step (a scan starts only once correlation
//   took every frame), so a run is the same sequence of frames on any machine.
// All methods are RT-safe: noexcept, no allocation.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>

#include "sempose/config/app_config.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {

class StageClock {
 public:
  virtual ~StageClock() = default;
  // When acquisition saw the frame whose scan ended at scan_end_ns.
  virtual std::int64_t seen_ns(std::int64_t scan_end_ns) const noexcept = 0;
  // When correlation starts on a frame seen at seen_ns (the previous pose done at prev_done_ns).
  virtual std::int64_t pose_start_ns(std::int64_t seen_ns, std::int64_t prev_done_ns) const noexcept = 0;
  // The compute time the stages account for (histograms, governor) given the measured one.
  virtual std::int64_t compute_ns(std::int64_t measured_ns) const noexcept = 0;
  // When the pose is done: it started at start_ns and took compute_ns; the tracker returned
  // at returned_ns (CLOCK_MONOTONIC).
  virtual std::int64_t pose_done_ns(std::int64_t start_ns, std::int64_t compute_ns,
                                    std::int64_t returned_ns) const noexcept = 0;
  // "Now" for the output stage: sending a pose done at pose_done_ns, or servicing the sink
  // (heartbeats) after the last pose done at pose_done_ns.
  virtual std::int64_t output_now_ns(std::int64_t pose_done_ns) const noexcept = 0;
  // True: acquisition starts a scan only once correlation took every frame (no drops).
  virtual bool lock_step() const noexcept = 0;
  // True: time passes by itself, so waiting for a scan means sleeping until it is due.
  virtual bool real_time() const noexcept = 0;
};

class LiveStageClock final : public StageClock {
 public:
  std::int64_t seen_ns(std::int64_t) const noexcept override { return rt::now_ns(); }
  std::int64_t pose_start_ns(std::int64_t, std::int64_t) const noexcept override { return rt::now_ns(); }
  std::int64_t compute_ns(std::int64_t measured_ns) const noexcept override { return measured_ns; }
  std::int64_t pose_done_ns(std::int64_t, std::int64_t, std::int64_t returned_ns) const noexcept override {
    return returned_ns;
  }
  std::int64_t output_now_ns(std::int64_t) const noexcept override { return rt::now_ns(); }
  bool lock_step() const noexcept override { return false; }
  bool real_time() const noexcept override { return true; }
};

class VirtualStageClock final : public StageClock {
 public:
  // modelled_compute_ns: the compute time every pose is said to take; 0: the measured one.
  explicit VirtualStageClock(std::int64_t modelled_compute_ns) noexcept : modelled_compute_ns_(modelled_compute_ns) {}
  std::int64_t seen_ns(std::int64_t scan_end_ns) const noexcept override { return scan_end_ns; }
  std::int64_t pose_start_ns(std::int64_t seen_ns, std::int64_t prev_done_ns) const noexcept override {
    return std::max(seen_ns, prev_done_ns);
  }
  std::int64_t compute_ns(std::int64_t measured_ns) const noexcept override {
    return modelled_compute_ns_ != 0 ? modelled_compute_ns_ : measured_ns;
  }
  std::int64_t pose_done_ns(std::int64_t start_ns, std::int64_t compute_ns, std::int64_t) const noexcept override {
    return start_ns + compute_ns;
  }
  std::int64_t output_now_ns(std::int64_t pose_done_ns) const noexcept override { return pose_done_ns; }
  bool lock_step() const noexcept override { return true; }
  bool real_time() const noexcept override { return false; }

 private:
  std::int64_t modelled_compute_ns_;
};

// The clock a configuration runs on: virtual when its scan source is the simulator or a
// replay on `clock: virtual`, live otherwise (the microscope, `clock: real`).
inline bool uses_virtual_clock(const config::AppConfig& cfg) {
  return (cfg.source == "sim" && cfg.sim.clock == "virtual") || (cfg.source == "replay" && cfg.replay.clock == "virtual");
}
inline std::unique_ptr<StageClock> make_stage_clock(const config::AppConfig& cfg) {
  if (uses_virtual_clock(cfg)) return std::make_unique<VirtualStageClock>(cfg.pipeline.virtual_compute_ns);
  return std::make_unique<LiveStageClock>();
}

}  // namespace sempose::pipeline
