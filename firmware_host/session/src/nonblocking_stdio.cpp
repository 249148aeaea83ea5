#include "sempose/session/nonblocking_stdio.hpp"

#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <string>

namespace sempose::session {
namespace {

struct Stream {
  int fd = -1;
  bool socket = false;
  std::atomic<std::uint64_t> lost_lines{0};
};

Stream g_out, g_err;
std::atomic<std::int64_t> g_patience_until_ns{0};

std::int64_t now_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// stdio hands over whole lines (line buffering); each piece of at most PIPE_BUF bytes goes to
// a pipe whole or not at all. Never blocks past the patience deadline; reports every byte as
// written so stdio neither keeps nor retries a dropped line (it would block or tear it later).
ssize_t write_lines(void* cookie, const char* buf, std::size_t size) {
  Stream& s = *static_cast<Stream*>(cookie);
  std::size_t done = 0;
  while (done < size) {
    const std::int64_t left_ns = g_patience_until_ns.load(std::memory_order_relaxed) - now_ns();
    pollfd p{s.fd, POLLOUT, 0};
    const int ready = ::poll(&p, 1, left_ns > 0 ? static_cast<int>(std::min<std::int64_t>(left_ns / 1'000'000 + 1, 60'000)) : 0);
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) break;  // no room in time
    const std::size_t chunk = std::min<std::size_t>(size - done, PIPE_BUF);
    const ssize_t w = s.socket ? ::send(s.fd, buf + done, chunk, MSG_DONTWAIT | MSG_NOSIGNAL) : ::write(s.fd, buf + done, chunk);
    if (w > 0) {
      done += static_cast<std::size_t>(w);
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) && left_ns > 0) continue;  // poll again, waits
    break;  // EAGAIN with no patience left, EPIPE (no reader), EIO, ...
  }
  if (done < size) {
    std::uint64_t lines = 0;
    for (std::size_t i = done; i < size; ++i) lines += buf[i] == '\n' ? 1 : 0;
    s.lost_lines.fetch_add(std::max<std::uint64_t>(lines, 1), std::memory_order_relaxed);
  }
  return static_cast<ssize_t>(size);
}

// fd as a non-blocking stream; nullptr when that cannot be made.
std::FILE* open_stream(int fd, Stream& s) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return nullptr;
  s.fd = fd;
  s.socket = S_ISSOCK(st.st_mode);
  if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) {
    // A description of our own with O_NONBLOCK: setting the flag on the inherited one would
    // change it for the shell and every other process sharing the pipe or terminal. When the
    // reopen fails (no /proc, a pipe without reader: ENXIO) poll() guards each write instead.
    const std::string self = "/proc/self/fd/" + std::to_string(fd);
    const int own = ::open(self.c_str(), O_WRONLY | O_NONBLOCK | O_NOCTTY);
    if (own >= 0) {
      ::dup2(own, fd);  // on failure fd stays as it was
      ::close(own);
    }
  }
  cookie_io_functions_t io{};
  io.write = write_lines;
  std::FILE* f = ::fopencookie(&s, "w", io);
  if (f == nullptr) return nullptr;
  ::setvbuf(f, nullptr, _IOLBF, 8192);
  return f;
}

}  // namespace

bool make_stdio_nonblocking() {
  std::fflush(stdout);
  std::fflush(stderr);
  std::FILE* out = open_stream(STDOUT_FILENO, g_out);
  std::FILE* err = open_stream(STDERR_FILENO, g_err);
  if (out == nullptr || err == nullptr) {
    if (out) std::fclose(out);
    if (err) std::fclose(err);
    return false;
  }
  // glibc: stdout and stderr are assignable; every later printf/fprintf(stderr) uses these.
  stdout = out;
  stderr = err;
  return true;
}

void set_stdio_patience_ms(int ms) {
  g_patience_until_ns.store(ms > 0 ? now_ns() + static_cast<std::int64_t>(ms) * 1'000'000 : 0, std::memory_order_relaxed);
}

std::uint64_t stdout_lines_lost() { return g_out.lost_lines.load(std::memory_order_relaxed); }
std::uint64_t stderr_lines_lost() { return g_err.lost_lines.load(std::memory_order_relaxed); }

}  // namespace sempose::session
