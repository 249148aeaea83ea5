// A scan source whose completion and clock a test controls (GPIO frame-sync tests).
#pragma once

#include "sempose/hal/scan_source.hpp"

namespace sempose::test {

namespace hal = sempose::hal;

class ScriptedSource final : public hal::ScanSource {
 public:
  const hal::ScanLimits& limits() const noexcept override { return limits_; }
  hal::StartResult start(const hal::ScanRequest&, hal::FrameSlot& slot) noexcept override {
    if (busy_) return hal::StartResult::kBusy;
    busy_ = true;
    done_ = false;
    slot_ = &slot;
    slot.meta = {};
    expected_ = now_ + 1'000'000;
    return hal::StartResult::kStarted;
  }
  hal::PollResult poll() noexcept override {
    if (!busy_) return hal::PollResult::kIdle;
    if (!done_) return hal::PollResult::kBusy;
    busy_ = false;
    slot_->meta.t_scan_end_ns = expected_;
    return hal::PollResult::kDone;
  }
  std::int64_t now_ns() const noexcept override { return now_; }
  std::int64_t expected_done_ns() const noexcept override { return busy_ ? expected_ : 0; }

  void finish() { done_ = true; }
  void set_now(std::int64_t t) { now_ = t; }

 private:
  hal::ScanLimits limits_;
  hal::FrameSlot* slot_ = nullptr;
  bool busy_ = false;
  bool done_ = false;
  std::int64_t now_ = 0;
  std::int64_t expected_ = 0;
};

}  // namespace sempose::test
