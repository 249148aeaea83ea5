// Monotonic nanosecond clock helpers (CLOCK_MONOTONIC, the clock of every timestamp in
// sempose, of GPIO edge events and of clock_nanosleep).
#pragma once

#include <cerrno>
#include <cstdint>
#include <ctime>

namespace sempose::rt {

inline constexpr std::int64_t kNsPerUs = 1'000;
inline constexpr std::int64_t kNsPerMs = 1'000'000;
inline constexpr std::int64_t kNsPerS = 1'000'000'000;

inline std::int64_t to_ns(const timespec& ts) noexcept {
  return static_cast<std::int64_t>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}
inline timespec to_timespec(std::int64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(ns % kNsPerS);
  return ts;
}

// vDSO call: no syscall, no allocation.
inline std::int64_t now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return to_ns(ts);
}

// Sleeps until an absolute CLOCK_MONOTONIC time; restarts after signals so a SIGUSR1
// (histogram dump) does not shorten a cycle.
inline void sleep_until_ns(std::int64_t deadline_ns) noexcept {
  const timespec ts = to_timespec(deadline_ns);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace sempose::rt
