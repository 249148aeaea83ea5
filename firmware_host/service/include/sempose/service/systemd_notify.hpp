// The service manager's notification socket (sd_notify(3) protocol): one datagram of
// newline-separated KEY=VALUE assignments to the AF_UNIX socket named by $NOTIFY_SOCKET
// (a path, or "@name" for the abstract namespace). systemd documents the protocol as stable
// and meant to be reimplemented; doing so keeps libsystemd out of the binary and lets a test
// read the datagrams from its own socket. Without $NOTIFY_SOCKET every call is a no-op, so
// `sempose run` behaves the same from a shell.
//
// Non-RT: called from the main thread only (sendto is a syscall; MSG_DONTWAIT so a manager
// that stopped reading never blocks the caller).
#pragma once

#include <sys/socket.h>
#include <sys/un.h>

#include <cstdint>
#include <string>
#include <string_view>

namespace sempose::service {

class SystemdNotifier {
 public:
  // Reads NOTIFY_SOCKET, WATCHDOG_USEC and WATCHDOG_PID (sd_watchdog_enabled(3): the
  // watchdog is ours only when WATCHDOG_PID is unset or equals getpid()).
  static SystemdNotifier from_environment();
  SystemdNotifier() = default;
  ~SystemdNotifier();
  SystemdNotifier(SystemdNotifier&& other) noexcept;
  SystemdNotifier& operator=(SystemdNotifier&&) = delete;
  SystemdNotifier(const SystemdNotifier&) = delete;
  SystemdNotifier& operator=(const SystemdNotifier&) = delete;

  bool enabled() const noexcept { return fd_ >= 0; }
  // The manager's WatchdogSec in ns; 0 when no watchdog is configured for this process.
  std::int64_t watchdog_interval_ns() const noexcept { return watchdog_ns_; }
  // Why the socket could not be used (empty when it works or was never asked for).
  const std::string& problem() const noexcept { return problem_; }

  // Sends `assignments` (e.g. "READY=1\nSTATUS=tracking") as one datagram. False on failure.
  bool notify(std::string_view assignments) noexcept;
  bool ready(std::string_view status);
  bool watchdog() noexcept { return notify("WATCHDOG=1"); }
  bool stopping() noexcept { return notify("STOPPING=1"); }
  bool status(std::string_view text);

 private:
  int fd_ = -1;
  sockaddr_un addr_{};
  socklen_t addr_len_ = 0;
  std::int64_t watchdog_ns_ = 0;
  std::string problem_;
};

}  // namespace sempose::service
