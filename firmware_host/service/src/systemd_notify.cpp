#include "sempose/service/systemd_notify.hpp"

#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <cstring>

namespace sempose::service {

SystemdNotifier SystemdNotifier::from_environment() {
  SystemdNotifier n;
  const char* socket_path = std::getenv("NOTIFY_SOCKET");
  if (socket_path == nullptr || socket_path[0] == '\0') return n;
  const std::size_t len = std::strlen(socket_path);
  if ((socket_path[0] != '/' && socket_path[0] != '@') || len >= sizeof(n.addr_.sun_path)) {
    n.problem_ = std::string("NOTIFY_SOCKET '") + socket_path + "' is not an absolute or abstract AF_UNIX address";
    return n;
  }
  n.addr_.sun_family = AF_UNIX;
  std::memcpy(n.addr_.sun_path, socket_path, len);
  if (socket_path[0] == '@') n.addr_.sun_path[0] = '\0';  // abstract namespace: no trailing NUL counted
  n.addr_len_ = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + len + (socket_path[0] == '@' ? 0 : 1));
  n.fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (n.fd_ < 0) {
    n.problem_ = std::string("notify socket: ") + std::strerror(errno);
    return n;
  }
  const char* usec = std::getenv("WATCHDOG_USEC");
  const char* pid = std::getenv("WATCHDOG_PID");
  // WATCHDOG_PID: the process the watchdog is meant for (absent: this one). One that is not a
  // process id leaves the watchdog unfed, as libsystemd's sd_watchdog_enabled() does, and is said:
  // "abc" was read as pid 0, silently not ours, and a WatchdogSec= unit killed the run without a
  // hint (hostile round 9).
  char* pid_end = nullptr;
  const long pid_value = pid == nullptr ? 0 : std::strtol(pid, &pid_end, 10);
  const bool pid_read = pid == nullptr || (pid_end != pid && *pid_end == '\0' && pid_value > 0);
  const bool ours = pid == nullptr || (pid_read && pid_value == static_cast<long>(::getpid()));
  if (usec != nullptr && !pid_read) {
    n.problem_ = std::string("WATCHDOG_PID '") + pid + "' is not a process id: the watchdog (WATCHDOG_USEC " + usec +
                 ") is not fed, and a unit with WatchdogSec= will stop this run";
  }
  if (usec != nullptr && ours) {
    char* end = nullptr;
    const long long us = std::strtoll(usec, &end, 10);
    // Bounded (found probing): 1 µs had the main loop send ~95,000 pings in 2.5 s, and beyond
    // ~9.2e15 µs the nanoseconds overflowed (no pings, no word). The loop pings every half
    // interval at most every kMinWatchdogUs / 2; a longer interval is pinged as the longest.
    constexpr long long kMinWatchdogUs = 20'000, kMaxWatchdogUs = 1'000'000'000'000;  // 20 ms .. ~11.6 days
    if (end != usec && *end == '\0' && us > 0) {
      n.watchdog_ns_ = std::clamp(us, kMinWatchdogUs, kMaxWatchdogUs) * 1000;
      if (us < kMinWatchdogUs) {
        n.problem_ = std::string("WATCHDOG_USEC ") + usec + " is below 20000 (20 ms): pinged every 10 ms, which such a " +
                     "watchdog will not wait for; set the unit's WatchdogSec= to 1 s or more";
      } else if (us > kMaxWatchdogUs) {
        n.problem_ = std::string("WATCHDOG_USEC ") + usec + " is beyond 1e12 (~11.6 days): pinged as if it were that";
      }
    } else {
      n.problem_ = std::string("WATCHDOG_USEC '") + usec + "' is not a positive number of microseconds";
    }
  }
  return n;
}

SystemdNotifier::SystemdNotifier(SystemdNotifier&& o) noexcept
    : fd_(o.fd_), addr_(o.addr_), addr_len_(o.addr_len_), watchdog_ns_(o.watchdog_ns_), problem_(std::move(o.problem_)) {
  o.fd_ = -1;
}

SystemdNotifier::~SystemdNotifier() {
  if (fd_ >= 0) ::close(fd_);
}

bool SystemdNotifier::notify(std::string_view assignments) noexcept {
  if (fd_ < 0) return false;
  const ssize_t n = ::sendto(fd_, assignments.data(), assignments.size(), MSG_NOSIGNAL | MSG_DONTWAIT,
                             reinterpret_cast<const sockaddr*>(&addr_), addr_len_);
  return n == static_cast<ssize_t>(assignments.size());
}

bool SystemdNotifier::ready(std::string_view status_text) {
  return notify("READY=1\nSTATUS=" + std::string(status_text));
}

bool SystemdNotifier::status(std::string_view text) { return notify("STATUS=" + std::string(text)); }

}  // namespace sempose::service
