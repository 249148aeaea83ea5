// The scan-source boundary: the simulated SEM, replay of recorded frames, and real scan
// generators all implement this, and only what scanning hardware does: how the stages pace
// themselves and stamp time (virtual time for tests) is the pipeline's StageClock. Every method after construction is RT-safe: noexcept, no
// allocation, no blocking. Errors are return codes.
//
// A real scan generator implements it as: start() writes the ROI and dwell to the
// generator's registers and arms a DMA transfer into the slot's (locked) pixel buffer;
// poll() checks the DMA-complete flag or reads a pending frame-done GPIO edge from
// wait_fd() without blocking; now_ns() is CLOCK_MONOTONIC.
#pragma once

#include <cstdint>

#include "sempose/config/scan_config.hpp"
#include "sempose/hal/frame.hpp"

namespace sempose::hal {

struct ScanRequest {
  Roi roi;
  std::uint32_t dwell_ns = 0;
  std::uint8_t target = 0;  // copied into FrameMeta::target
};

// What the scan generator can do (from config, section `scan:`); one definition, in config.
using ScanLimits = config::ScanLimits;

// A source starting the scan of req (dwell already checked and rounded): the frame's identity
// fields, status OK and every time stamp "not reached". The one way all sources fill them;
// the source then sets the times it knows (and the truth, when simulated).
inline void begin_frame_meta(FrameMeta& m, const ScanRequest& req, const ScanLimits& limits, std::uint32_t dwell_ns,
                             std::uint64_t seq) noexcept {
  m.seq = seq;
  m.roi = req.roi;
  m.field_w = limits.field_w;
  m.field_h = limits.field_h;
  m.dwell_ns = dwell_ns;
  m.bits = limits.bits;
  m.target = req.target;
  m.status = FrameStatus::kOk;
  m.t_scan_start_ns = m.t_scan_end_ns = m.t_seen_ns = m.t_pose_done_ns = 0;
}

enum class StartResult : std::uint8_t {
  kStarted = 0,
  kBusy,         // a scan is still in progress
  kBadRequest,   // ROI outside the field or above the max size, dwell outside limits
  kNoRoom,       // the slot's buffer is smaller than the ROI
  kEnded,        // a finite source (replay) has no more frames
};

enum class PollResult : std::uint8_t {
  kIdle = 0,  // no scan started
  kBusy,      // scanning
  kDone,      // the slot passed to start() is complete (meta and pixels filled)
  kError,     // the scan failed; the slot's meta.status says why; the source is idle again
};

class ScanSource {
 public:
  virtual ~ScanSource() = default;
  virtual const ScanLimits& limits() const noexcept = 0;
  // Begins scanning req into slot. The caller must not touch the slot until poll() returns
  // kDone or kError.
  virtual StartResult start(const ScanRequest& req, FrameSlot& slot) noexcept = 0;
  // ISR-like: only checks whether the scan in progress is complete.
  virtual PollResult poll() noexcept = 0;
  // The source's clock: CLOCK_MONOTONIC for live sources, a virtual clock otherwise.
  virtual std::int64_t now_ns() const noexcept = 0;
  // When the scan in progress is expected to complete (for sleep-then-poll); 0 if idle.
  virtual std::int64_t expected_done_ns() const noexcept = 0;
  // An fd that becomes readable when a scan completes (e.g. a GPIO frame-done edge), so a
  // caller can wait in poll(2) with a timeout; -1 when the source has none.
  virtual int wait_fd() const noexcept { return -1; }
};

}  // namespace sempose::hal
