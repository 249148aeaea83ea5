// Linux SocketCAN (CAN_RAW) channel. Non-blocking socket, send(MSG_DONTWAIT) — EAGAIN and
// ENOBUFS count as dropped, never block; a small SO_SNDBUF makes the kernel answer EAGAIN
// before the device queue overflows. Error frames (ACK, controller, bus-off) are subscribed
// and folded into the bus state. CAN FD (CAN_RAW_FD_FRAMES) when the interface MTU is 72
// and the configuration allows it.
//
// An interface that goes away (`ip link del`, a USB-CAN adapter unplugged) leaves the socket
// bound to a dead ifindex: the kernel unbinds it and every send fails with ENXIO/ENODEV. The
// channel marks itself detached; flush() (non-RT, periodic) looks the name up again and, once
// the interface is back, opens a fresh socket with the same options and dup2()s it over the
// old descriptor — atomic for the RT thread, which keeps calling send()/recv() on the same fd
// number and never sees a closed one. A link merely set down keeps its ifindex and needs none
// of this (sends fail with ENETDOWN until it is up again).
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "sempose/hal/can_channel.hpp"
#include "sempose/rt/result.hpp"

namespace sempose::hal {

enum class CanFdMode : std::uint8_t { kAuto = 0, kOff, kOn };

struct SocketCanOptions {
  std::string interface;        // e.g. "can0", "vcan0"
  CanFdMode fd = CanFdMode::kOff;  // classic CAN unless asked: kAuto uses FD when the MTU is 72
  int sndbuf_bytes = 16384;     // 0 = kernel default; the kernel enforces its own minimum
  int rx_id = -1;               // receive only this standard id (the command id); -1 = all
  // A passive bus (ACK errors: nobody listening) is reported active again after this long
  // without error frames, for controllers/kernels that never send CAN_ERR_CRTL_ACTIVE.
  std::int64_t passive_hold_ns = 1'000'000'000;
};

class SocketCanChannel final : public CanChannel {
 public:
  // Setup: opens, binds, sets options. Returns nullptr with a message naming the interface,
  // the failing step and errno text (e.g. "no such device", "kernel has no CAN support").
  static std::unique_ptr<SocketCanChannel> open(const SocketCanOptions& options, rt::Status& status);
  ~SocketCanChannel() override;

  CanSendResult send(const CanFrame& frame, std::int64_t t_ns) noexcept override;
  bool receive(CanFrame& out) noexcept override;
  // Non-RT: while detached, binds again once the interface exists (same name, options and
  // CAN FD mode); the reason a re-bind was refused is in rebind_status().
  void flush() override;
  bool detached() const noexcept override { return detached_.load(std::memory_order_relaxed); }
  const rt::Status& rebind_status() const noexcept { return rebind_status_; }
  bool fd_enabled() const noexcept override { return fd_; }
  const char* name() const noexcept override { return interface_.c_str(); }
  int fd() const noexcept { return sock_; }
  int mtu() const noexcept { return mtu_; }
  int sndbuf_bytes() const noexcept { return sndbuf_; }

 private:
  SocketCanChannel() = default;
  // A new CAN_RAW socket bound to the interface with options_ (setup and re-bind); -1 with
  // the failing step in status. mtu receives the interface's MTU.
  int make_socket(int& mtu, rt::Status& status) const;
  void fold_error_frame(std::uint32_t can_id, const std::uint8_t* data) noexcept;
  void note_errno(int e) noexcept;

  SocketCanOptions options_;
  std::string interface_;
  std::atomic<bool> detached_{false};
  rt::Status rebind_status_;
  int sock_ = -1;
  int mtu_ = 0;
  int sndbuf_ = 0;
  bool fd_ = false;
  std::int64_t passive_hold_ns_ = 0;
  std::int64_t last_error_ns_ = 0;
};

}  // namespace sempose::hal
