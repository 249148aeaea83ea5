// (ok, message) result for setup and configuration steps (ros2_control style): setup code
// reports what went wrong in words a user can act on, without throwing.
#pragma once

#include <string>
#include <utility>

namespace sempose::rt {

// ok with a non-empty message is a warning: it worked, degraded (say, no SCHED_FIFO).
struct Status {
  bool ok = true;
  std::string message;  // on failure: names the problem and the remedy; on success: a warning

  static Status success() { return {}; }
  static Status failure(std::string why) { return {false, std::move(why)}; }
  explicit operator bool() const noexcept { return ok; }
};

}  // namespace sempose::rt
