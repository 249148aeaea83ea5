// Stall watchdog for the non-RT main loop: frames must keep coming while the pipeline runs.
// No new frame for longer than the timeout is a stall (reported once, at once), cleared as
// soon as frames come again. Pure and header-only: fed the frame counter and the time.
#pragma once

#include <algorithm>
#include <cstdint>

#include "sempose/hal/scan_source.hpp"

namespace sempose::pipeline {

class StallWatchdog {
 public:
  enum class Change { kNone, kStalled, kRecovered };

  // Longest a healthy source can take for one frame is the whole field at the slowest dwell
  // plus flyback; a stall is no frame for 3 of those, and never less than min_ns (2 s).
  static std::int64_t timeout_for(const hal::ScanLimits& l, std::int64_t min_ns = 2'000'000'000) {
    const double frame_ns = static_cast<double>(l.field_w) * l.field_h * l.max_dwell_ns +
                            static_cast<double>(l.field_h) * l.line_flyback_ns;
    return static_cast<std::int64_t>(std::clamp(3.0 * frame_ns, static_cast<double>(min_ns), 3.6e12));
  }

  StallWatchdog(std::int64_t timeout_ns, std::int64_t t0_ns) noexcept : timeout_ns_(timeout_ns), last_change_ns_(t0_ns) {}

  Change update(std::uint64_t frames, std::int64_t now_ns) noexcept {
    if (frames != frames_) {
      frames_ = frames;
      last_change_ns_ = now_ns;
      if (stalled_) {
        stalled_ = false;
        return Change::kRecovered;
      }
      return Change::kNone;
    }
    if (!stalled_ && now_ns - last_change_ns_ > timeout_ns_) {
      stalled_ = true;
      ++stalls_;
      return Change::kStalled;
    }
    return Change::kNone;
  }
  bool stalled() const noexcept { return stalled_; }
  std::uint64_t stalls() const noexcept { return stalls_; }
  std::int64_t silent_ns(std::int64_t now_ns) const noexcept { return now_ns - last_change_ns_; }

 private:
  std::int64_t timeout_ns_;
  std::int64_t last_change_ns_;
  std::uint64_t frames_ = 0;
  bool stalled_ = false;
  std::uint64_t stalls_ = 0;
};

}  // namespace sempose::pipeline
