// The stall rule, written once: a counter that must keep moving (frames scanned, poses made,
// poses published) and has not moved for the timeout or longer is stalled (ProgressWatch).
// StallWatchdog applies it to the source's frames for the non-RT main loop: a stall is
// reported once, at once, and cleared as soon as frames come again; the service watchdog
// (service::ProgressMonitor) applies it to each RT stage. Pure and header-only: fed the
// counter and the time.
#pragma once

#include <algorithm>
#include <cstdint>

#include "sempose/hal/scan_source.hpp"

namespace sempose::pipeline {

class ProgressWatch {
 public:
  ProgressWatch(std::int64_t timeout_ns, std::int64_t t0_ns) noexcept : timeout_ns_(timeout_ns), last_move_ns_(t0_ns) {}
  // Takes a sample; true when stalled. expect_progress false (idle on purpose): never
  // stalled, and the silence restarts.
  bool stalled(std::uint64_t count, std::int64_t now_ns, bool expect_progress = true) noexcept {
    if (count != last_count_ || !expect_progress) {
      last_count_ = count;
      last_move_ns_ = now_ns;
      return false;
    }
    return now_ns - last_move_ns_ >= timeout_ns_;
  }
  std::int64_t idle_ns(std::int64_t now_ns) const noexcept { return now_ns - last_move_ns_; }

 private:
  std::int64_t timeout_ns_;
  std::int64_t last_move_ns_;
  std::uint64_t last_count_ = 0;
};

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

  StallWatchdog(std::int64_t timeout_ns, std::int64_t t0_ns) noexcept : watch_(timeout_ns, t0_ns) {}

  Change update(std::uint64_t frames, std::int64_t now_ns) noexcept {
    const bool was = stalled_;
    stalled_ = watch_.stalled(frames, now_ns);
    if (stalled_ && !was) ++stalls_;
    return stalled_ == was ? Change::kNone : stalled_ ? Change::kStalled : Change::kRecovered;
  }
  bool stalled() const noexcept { return stalled_; }
  std::uint64_t stalls() const noexcept { return stalls_; }
  std::int64_t silent_ns(std::int64_t now_ns) const noexcept { return watch_.idle_ns(now_ns); }

 private:
  ProgressWatch watch_;
  bool stalled_ = false;
  std::uint64_t stalls_ = 0;
};

}  // namespace sempose::pipeline
