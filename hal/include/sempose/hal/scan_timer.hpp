// Clock and completion shared by the sources that produce the whole frame in start() (the
// simulated SEM, replay): a scan is done once its modelled scan time (w·h·dwell + h·flyback)
// has passed on CLOCK_MONOTONIC, or at once on the virtual clock, which then jumps to the
// scan end. RT-safe: noexcept, no allocation.
#pragma once

#include <algorithm>
#include <cstdint>

#include "sempose/hal/scan_source.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::hal {

class ScanTimer {
 public:
  // Virtual time starts at 1 s: 0 means "not reached" in FrameMeta.
  static constexpr std::int64_t kVirtualEpochNs = 1'000'000'000;

  explicit ScanTimer(bool virtual_time) noexcept : virtual_(virtual_time) {}

  bool is_virtual() const noexcept { return virtual_; }
  bool busy() const noexcept { return slot_ != nullptr; }
  std::int64_t now_ns() const noexcept { return virtual_ ? virtual_now_ns_ : rt::now_ns(); }
  std::int64_t expected_done_ns() const noexcept { return slot_ ? end_ns_ : 0; }
  void advance_virtual_ns(std::int64_t ns) noexcept {
    if (virtual_ && ns > 0) virtual_now_ns_ += ns;
  }

  // Fills the identity and timing fields of slot.meta for req (dwell already checked and
  // rounded) scanned from t0_ns, and arms completion. The caller fills pixels and truth.
  void begin(FrameSlot& slot, const ScanRequest& req, const ScanLimits& limits, std::uint32_t dwell_ns,
             std::uint64_t seq, std::int64_t t0_ns) noexcept {
    FrameMeta& m = slot.meta;
    begin_frame_meta(m, req, limits, dwell_ns, seq);
    m.t_scan_start_ns = t0_ns;
    m.t_scan_end_ns = t0_ns + limits.scan_time_ns(req.roi.w, req.roi.h, dwell_ns);
    end_ns_ = m.t_scan_end_ns;
    slot_ = &slot;
  }

  PollResult poll() noexcept {
    if (slot_ == nullptr) return PollResult::kIdle;
    if (virtual_) {
      virtual_now_ns_ = std::max(virtual_now_ns_, end_ns_);
    } else if (rt::now_ns() < end_ns_) {
      return PollResult::kBusy;
    }
    slot_ = nullptr;
    return PollResult::kDone;
  }

 private:
  bool virtual_;
  std::int64_t virtual_now_ns_ = kVirtualEpochNs;
  FrameSlot* slot_ = nullptr;
  std::int64_t end_ns_ = 0;
};

// A scan source whose frames complete on a ScanTimer (the simulator, replay): the timing half
// of ScanSource, written once. Derived sources implement limits() and start().
class TimedScanSource : public ScanSource {
 public:
  PollResult poll() noexcept override { return timer_.poll(); }
  std::int64_t now_ns() const noexcept override { return timer_.now_ns(); }
  std::int64_t expected_done_ns() const noexcept override { return timer_.expected_done_ns(); }
  // The simulator's and replay's own clock (not part of ScanSource): deterministic virtual
  // time, which tests may let pass without scanning.
  bool is_virtual_time() const noexcept { return timer_.is_virtual(); }
  void advance_virtual_ns(std::int64_t ns) noexcept { timer_.advance_virtual_ns(ns); }

 protected:
  explicit TimedScanSource(bool virtual_time) noexcept : timer_(virtual_time) {}
  ScanTimer timer_;
};

}  // namespace sempose::hal
