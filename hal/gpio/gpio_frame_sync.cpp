// Frame-sync input over the libgpiod v1 C API. See gpio_frame_sync.hpp.
#include "sempose/hal/gpio_frame_sync.hpp"

#include <fcntl.h>
#include <gpiod.h>
#include <poll.h>

#include <cerrno>
#include <cstring>

#include "sempose/rt/clock.hpp"
#include "sempose/hal/gpio_chip_open.hpp"

namespace sempose::hal {

std::unique_ptr<GpioFrameSync> GpioFrameSync::open(const GpioLineOptions& o, rt::Status& status) {
  const std::string where = "gpio.chip '" + o.chip + "' gpio.frame_sync_line " + std::to_string(o.line) + ": ";
  std::unique_ptr<GpioFrameSync> s(new GpioFrameSync());
  std::string why;
  s->chip_ = open_gpio_chip(o.chip, why);
  if (s->chip_ == nullptr) {
    status = rt::Status::failure(where + "cannot open the chip: " + why +
                                 " (`gpiodetect` lists chips; this kernel may have no GPIO support)");
    return nullptr;
  }
  const unsigned lines = gpiod_chip_num_lines(s->chip_);
  if (o.line < 0 || static_cast<unsigned>(o.line) >= lines) {
    status = rt::Status::failure(where + "line offset outside the chip's range [0, " + std::to_string(lines) + ")");
    return nullptr;
  }
  s->line_ = gpiod_chip_get_line(s->chip_, static_cast<unsigned>(o.line));
  const int flags = o.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (s->line_ == nullptr ||
      gpiod_line_request_rising_edge_events_flags(s->line_, o.consumer.c_str(), flags) != 0) {
    status = rt::Status::failure(where + "cannot request rising-edge events: " + std::strerror(errno) +
                                 " (line busy? `gpioinfo` shows its consumer)");
    return nullptr;
  }
  s->fd_ = gpiod_line_event_get_fd(s->line_);
  if (s->fd_ < 0) {
    status = rt::Status::failure(where + "no event fd: " + std::strerror(errno));
    return nullptr;
  }
  // Non-blocking reads: read_edges() never waits, it takes what the kernel queued (up to 16).
  const int fl = ::fcntl(s->fd_, F_GETFL);
  if (fl < 0 || ::fcntl(s->fd_, F_SETFL, fl | O_NONBLOCK) < 0) {
    status = rt::Status::failure(where + "cannot make the event fd non-blocking: " + std::strerror(errno));
    return nullptr;
  }
  status = rt::Status::success();
  return s;
}

GpioFrameSync::~GpioFrameSync() {
  if (line_ != nullptr) gpiod_line_release(line_);
  if (chip_ != nullptr) gpiod_chip_close(chip_);
}

int GpioFrameSync::read_edges(std::int64_t* t_edge_ns, int max) noexcept {
  int n = 0;
  while (n < max) {
    gpiod_line_event ev{};
    if (gpiod_line_event_read_fd(fd_, &ev) != 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) break;
      return n > 0 ? n : -1;
    }
    if (ev.event_type != GPIOD_LINE_EVENT_RISING_EDGE) continue;
    t_edge_ns[n++] = rt::to_ns(ev.ts);
  }
  return n;
}

bool GpioFrameSync::wait(std::int64_t timeout_ns) const noexcept {
  pollfd p{fd_, POLLIN, 0};
  const int ms = timeout_ns <= 0 ? 0 : static_cast<int>((timeout_ns + 999'999) / 1'000'000);
  return ::poll(&p, 1, ms) > 0 && (p.revents & POLLIN) != 0;
}

}  // namespace sempose::hal
