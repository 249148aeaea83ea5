// SocketCAN (CAN_RAW) implementation of CanChannel. See can_socket_channel.hpp.
#include "sempose/hal/can_socket_channel.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "sempose/rt/clock.hpp"

namespace sempose::hal {
namespace {

std::string errno_text(int e) {
  std::string s = std::strerror(e);
  if (e == EAFNOSUPPORT || e == EPROTONOSUPPORT)
    s += " (this kernel has no CAN support: load can, can-raw and the driver, e.g. vcan)";
  if (e == ENODEV) s += " (no such interface: `ip link` lists them; vcan: `ip link add dev vcan0 type vcan`)";
  if (e == ENETDOWN) s += " (interface is down: `ip link set <if> up`)";
  return s;
}

}  // namespace

std::unique_ptr<SocketCanChannel> SocketCanChannel::open(const SocketCanOptions& o, rt::Status& status) {
  if (o.interface.empty() || o.interface.size() >= IFNAMSIZ) {
    status = rt::Status::failure("can.interface '" + o.interface + "': interface name must be 1.." +
                                 std::to_string(IFNAMSIZ - 1) + " characters");
    return nullptr;
  }
  std::unique_ptr<SocketCanChannel> ch(new SocketCanChannel());
  ch->options_ = o;
  ch->interface_ = o.interface;
  ch->passive_hold_ns_ = o.passive_hold_ns;
  ch->sock_ = ch->make_socket(ch->mtu_, status);
  if (ch->sock_ < 0) return nullptr;
  ch->fd_ = ch->mtu_ == static_cast<int>(CANFD_MTU) && o.fd != CanFdMode::kOff;
  socklen_t len = sizeof ch->sndbuf_;
  ::getsockopt(ch->sock_, SOL_SOCKET, SO_SNDBUF, &ch->sndbuf_, &len);
  status = rt::Status::success();
  return ch;
}

int SocketCanChannel::make_socket(int& mtu, rt::Status& status) const {
  const SocketCanOptions& o = options_;
  const std::string where = "can.interface '" + o.interface + "': ";
  int sock = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  auto fail = [&](const std::string& step, int e) {
    status = rt::Status::failure(where + step + ": " + errno_text(e));
    if (sock >= 0) ::close(sock);
    return -1;
  };
  if (sock < 0) return fail("socket(PF_CAN, SOCK_RAW, CAN_RAW)", errno);

  ifreq ifr{};
  std::strncpy(ifr.ifr_name, o.interface.c_str(), IFNAMSIZ - 1);
  if (::ioctl(sock, SIOCGIFINDEX, &ifr) < 0) return fail("SIOCGIFINDEX", errno);
  const int ifindex = ifr.ifr_ifindex;
  if (::ioctl(sock, SIOCGIFMTU, &ifr) < 0) return fail("SIOCGIFMTU", errno);
  mtu = ifr.ifr_mtu;

  const bool fd_capable = mtu == static_cast<int>(CANFD_MTU);
  if (o.fd == CanFdMode::kOn && !fd_capable) {
    status = rt::Status::failure(where + "can.fd is 'on' but the interface MTU is " + std::to_string(mtu) +
                                 " (CAN FD needs 72: `ip link set " + o.interface + " mtu 72`, or set can.fd: auto)");
    ::close(sock);
    return -1;
  }
  if (fd_capable && o.fd != CanFdMode::kOff) {
    const int on = 1;
    if (::setsockopt(sock, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0)
      return fail("setsockopt(CAN_RAW_FD_FRAMES)", errno);
  }
  // Error frames: a missing ACK (nobody listening), controller state changes, bus-off.
  const can_err_mask_t err_mask = CAN_ERR_ACK | CAN_ERR_CRTL | CAN_ERR_BUSOFF | CAN_ERR_RESTARTED;
  if (::setsockopt(sock, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0)
    return fail("setsockopt(CAN_RAW_ERR_FILTER)", errno);
  if (o.rx_id >= 0) {
    can_filter filter{};
    filter.can_id = static_cast<canid_t>(o.rx_id);
    filter.can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;  // exactly this standard data frame
    if (::setsockopt(sock, SOL_CAN_RAW, CAN_RAW_FILTER, &filter, sizeof filter) < 0)
      return fail("setsockopt(CAN_RAW_FILTER)", errno);
  }
  if (o.sndbuf_bytes > 0) {
    if (::setsockopt(sock, SOL_SOCKET, SO_SNDBUF, &o.sndbuf_bytes, sizeof o.sndbuf_bytes) < 0)
      return fail("setsockopt(SO_SNDBUF)", errno);
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifindex;
  if (::bind(sock, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) return fail("bind", errno);
  return sock;
}

void SocketCanChannel::flush() {
  if (!detached()) return;
  if (if_nametoindex(interface_.c_str()) == 0) {
    rebind_status_ = rt::Status::failure("can.interface '" + interface_ + "' is gone; waiting for it to come back");
    return;
  }
  int mtu = 0;
  rt::Status st;
  const int sock = make_socket(mtu, st);
  if (sock < 0) {
    rebind_status_ = st;
    return;
  }
  // The RT thread builds its frames for the CAN FD mode chosen at setup: an interface back
  // with another MTU would turn every pose into an error, so it is not taken.
  const bool fd = mtu == static_cast<int>(CANFD_MTU) && options_.fd != CanFdMode::kOff;
  if (fd != fd_) {
    ::close(sock);
    rebind_status_ = rt::Status::failure("can.interface '" + interface_ + "' is back with MTU " + std::to_string(mtu) +
                                         ", not the " + std::to_string(mtu_) + " it had at start; not re-bound");
    return;
  }
  // Atomic for the RT thread: its next send()/recv() on sock_ reaches the new socket; one in
  // flight finishes on the old one, which the kernel frees once that call returns.
  if (::dup3(sock, sock_, O_CLOEXEC) < 0) {
    rebind_status_ = rt::Status::failure("can.interface '" + interface_ + "': dup3: " + errno_text(errno));
    ::close(sock);
    return;
  }
  ::close(sock);
  counters_.bus_state.store(static_cast<std::uint8_t>(CanBusState::kActive), std::memory_order_relaxed);
  detached_.store(false, std::memory_order_relaxed);
  CanChannelCounters::bump(counters_.rebinds);
  rebind_status_ = rt::Status::success();
}

void SocketCanChannel::note_errno(int e) noexcept {
  // ENXIO: sent on a socket the kernel unbound when its interface was unregistered; ENODEV:
  // the socket's pending error from that unregistration.
  if (e == ENXIO || e == ENODEV) detached_.store(true, std::memory_order_relaxed);
}

SocketCanChannel::~SocketCanChannel() {
  if (sock_ >= 0) ::close(sock_);
}

CanSendResult SocketCanChannel::send(const CanFrame& f, std::int64_t /*t_ns*/) noexcept {
  if (bus_state() == CanBusState::kBusOff) {
    // The controller is off the bus until restarted; queueing would only fill the socket.
    CanChannelCounters::bump(counters_.tx_dropped);
    return CanSendResult::kDropped;
  }
  canfd_frame raw{};
  raw.can_id = f.extended() ? ((f.id & CAN_EFF_MASK) | CAN_EFF_FLAG) : (f.id & CAN_SFF_MASK);
  if (f.remote()) raw.can_id |= CAN_RTR_FLAG;
  std::size_t size = CAN_MTU;
  if (f.fd()) {
    if (!fd_ || f.len > CANFD_MAX_DLEN) {
      CanChannelCounters::bump(counters_.tx_errors);
      return CanSendResult::kError;
    }
    size = CANFD_MTU;
    raw.flags = static_cast<__u8>((f.flags & CanFrame::kBrs) ? CANFD_BRS : 0);
  } else if (f.len > CAN_MAX_DLEN) {
    CanChannelCounters::bump(counters_.tx_errors);
    return CanSendResult::kError;
  }
  raw.len = f.len;
  std::memcpy(raw.data, f.data, f.len);
  const ssize_t n = ::send(sock_, &raw, size, MSG_DONTWAIT);
  if (n == static_cast<ssize_t>(size)) {
    CanChannelCounters::bump(counters_.tx_frames);
    return CanSendResult::kSent;
  }
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
    CanChannelCounters::bump(counters_.tx_dropped);
    return CanSendResult::kDropped;
  }
  if (n < 0) note_errno(errno);
  CanChannelCounters::bump(counters_.tx_errors);
  return CanSendResult::kError;
}

void SocketCanChannel::fold_error_frame(std::uint32_t can_id, const std::uint8_t* data) noexcept {
  CanChannelCounters::bump(counters_.error_frames);
  last_error_ns_ = rt::now_ns();
  auto state = bus_state();
  if (can_id & CAN_ERR_BUSOFF) {
    state = CanBusState::kBusOff;
  } else if (can_id & CAN_ERR_RESTARTED) {
    state = CanBusState::kActive;
  } else {
    if (can_id & CAN_ERR_CRTL) {
      const std::uint8_t ctrl = data[1];
      if (ctrl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) state = CanBusState::kPassive;
#ifdef CAN_ERR_CRTL_ACTIVE
      if (ctrl & CAN_ERR_CRTL_ACTIVE) state = CanBusState::kActive;
#endif
    }
    // No ACK: nobody else on the bus; the sender's TEC climbs to error passive.
    if ((can_id & CAN_ERR_ACK) && state == CanBusState::kActive) state = CanBusState::kPassive;
  }
  counters_.bus_state.store(static_cast<std::uint8_t>(state), std::memory_order_relaxed);
}

bool SocketCanChannel::receive(CanFrame& out) noexcept {
  // Bounded: at most a socket's worth of frames per call, so the caller's cycle stays bounded.
  for (int i = 0; i < 64; ++i) {
    canfd_frame raw{};
    const ssize_t n = ::recv(sock_, &raw, sizeof raw, MSG_DONTWAIT);
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) note_errno(errno);
    if (n != static_cast<ssize_t>(CAN_MTU) && n != static_cast<ssize_t>(CANFD_MTU)) break;
    if (raw.can_id & CAN_ERR_FLAG) {
      fold_error_frame(raw.can_id, raw.data);
      continue;
    }
    out.flags = 0;
    if (raw.can_id & CAN_EFF_FLAG) {
      out.flags |= CanFrame::kExtended;
      out.id = raw.can_id & CAN_EFF_MASK;
    } else {
      out.id = raw.can_id & CAN_SFF_MASK;
    }
    if (raw.can_id & CAN_RTR_FLAG) out.flags |= CanFrame::kRemote;
    if (n == static_cast<ssize_t>(CANFD_MTU)) out.flags |= CanFrame::kFd;
    if (raw.flags & CANFD_BRS) out.flags |= CanFrame::kBrs;
    out.len = raw.len > CANFD_MAX_DLEN ? CANFD_MAX_DLEN : raw.len;
    std::memcpy(out.data, raw.data, out.len);
    CanChannelCounters::bump(counters_.rx_frames);
    return true;
  }
  // Error passive decays back to active after a quiet period (see SocketCanOptions).
  if (bus_state() == CanBusState::kPassive && rt::now_ns() - last_error_ns_ > passive_hold_ns_)
    counters_.bus_state.store(static_cast<std::uint8_t>(CanBusState::kActive), std::memory_order_relaxed);
  return false;
}

}  // namespace sempose::hal
