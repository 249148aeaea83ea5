// LinuxProbe: RTM_GETLINK for one interface (IFLA_LINKINFO -> kind, and for real CAN
// controllers IFLA_CAN_BITTIMING / IFLA_CAN_STATE, as `ip -details link show` prints them),
// and libgpiod v1 for a line's owner (as `gpioinfo` prints it).
#include <fcntl.h>
#include <gpiod.h>
#include <linux/comedi.h>
#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "sempose/hal/gpio_chip_open.hpp"
#include "sempose/check_rt/live_probe.hpp"

namespace sempose::check_rt {
namespace {

const char* can_state_name(std::uint32_t s) {
  switch (s) {
    case CAN_STATE_ERROR_ACTIVE: return "error-active";
    case CAN_STATE_ERROR_WARNING: return "error-warning";
    case CAN_STATE_ERROR_PASSIVE: return "error-passive";
    case CAN_STATE_BUS_OFF: return "bus-off";
    case CAN_STATE_STOPPED: return "stopped";
    case CAN_STATE_SLEEPING: return "sleeping";
    default: return "unknown";
  }
}

// Walks the rtattrs of [data, data+len).
template <typename Fn>
void for_each_attr(const void* data, int len, Fn&& fn) {
  for (auto* a = static_cast<const rtattr*>(data); RTA_OK(a, len); a = RTA_NEXT(a, len)) fn(a);
}

}  // namespace

std::optional<CanLinkDetails> LinuxProbe::can_link(const std::string& interface) {
  const unsigned index = if_nametoindex(interface.c_str());
  if (index == 0) return std::nullopt;
  const int fd = ::socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE);
  if (fd < 0) return std::nullopt;
  struct {
    nlmsghdr nh;
    ifinfomsg ifi;
  } req{};
  req.nh.nlmsg_len = NLMSG_LENGTH(sizeof(ifinfomsg));
  req.nh.nlmsg_type = RTM_GETLINK;
  req.nh.nlmsg_flags = NLM_F_REQUEST;
  req.nh.nlmsg_seq = 1;
  req.ifi.ifi_family = AF_UNSPEC;
  req.ifi.ifi_index = static_cast<int>(index);
  std::optional<CanLinkDetails> out;
  alignas(nlmsghdr) char buf[16384];
  if (::send(fd, &req, req.nh.nlmsg_len, 0) >= 0) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    int len = static_cast<int>(n);
    for (auto* nh = reinterpret_cast<const nlmsghdr*>(buf); n > 0 && NLMSG_OK(nh, len); nh = NLMSG_NEXT(nh, len)) {
      if (nh->nlmsg_type != RTM_NEWLINK) continue;
      CanLinkDetails d;
      const auto* ifi = static_cast<const ifinfomsg*>(NLMSG_DATA(nh));
      for_each_attr(IFLA_RTA(ifi), static_cast<int>(IFLA_PAYLOAD(nh)), [&](const rtattr* a) {
        if (a->rta_type != IFLA_LINKINFO) return;
        for_each_attr(RTA_DATA(a), static_cast<int>(RTA_PAYLOAD(a)), [&](const rtattr* li) {
          if (li->rta_type == IFLA_INFO_KIND) {
            d.kind.assign(static_cast<const char*>(RTA_DATA(li)), strnlen(static_cast<const char*>(RTA_DATA(li)), RTA_PAYLOAD(li)));
          } else if (li->rta_type == IFLA_INFO_DATA) {
            for_each_attr(RTA_DATA(li), static_cast<int>(RTA_PAYLOAD(li)), [&](const rtattr* c) {
              if (c->rta_type == IFLA_CAN_BITTIMING && RTA_PAYLOAD(c) >= sizeof(can_bittiming)) {
                can_bittiming bt;
                std::memcpy(&bt, RTA_DATA(c), sizeof bt);
                d.bitrate = bt.bitrate;
              } else if (c->rta_type == IFLA_CAN_STATE && RTA_PAYLOAD(c) >= sizeof(std::uint32_t)) {
                std::uint32_t s = 0;
                std::memcpy(&s, RTA_DATA(c), sizeof s);
                d.state = can_state_name(s);
              }
            });
          }
        });
      });
      out = d;
      break;
    }
  }
  ::close(fd);
  return out;
}

GpioLineUse LinuxProbe::gpio_line(const std::string& chip_name, int offset) {
  GpioLineUse u;
  // The cause run names too (a file, FIFO or folder as the chip was "No such file or directory"
  // here while run said what it is; hostile round 11).
  gpiod_chip* chip = hal::open_gpio_chip(chip_name, u.chip_problem);
  if (chip == nullptr) return u;
  u.chip_found = true;
  if (offset >= 0 && static_cast<unsigned>(offset) < gpiod_chip_num_lines(chip)) {
    gpiod_line* line = gpiod_chip_get_line(chip, static_cast<unsigned>(offset));
    if (line != nullptr) {
      u.line_exists = true;
      u.used = gpiod_line_is_used(line);
      const char* c = gpiod_line_consumer(line);
      if (c != nullptr) u.consumer = c;
    }
  }
  gpiod_chip_close(chip);
  return u;
}

std::string LinuxProbe::comedi_problem(const std::string& path) {
  // As `run` opens it (hal/comedi: ComediDevice), without blocking on a FIFO.
  const int fd = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return std::string("cannot be opened (") + std::strerror(errno) + ")";
  comedi_devinfo info{};
  const bool comedi = ::ioctl(fd, COMEDI_DEVINFO, &info) == 0;
  const int err = errno;
  ::close(fd);
  return comedi ? std::string() : std::string("is not a Comedi device (COMEDI_DEVINFO: ") + std::strerror(err) + ")";
}

}  // namespace sempose::check_rt
