// The CAN boundary (Lely style): one abstract channel, one implementation per platform —
// SocketCanChannel (Linux CAN_RAW), CandumpLogChannel (a candump -l file, no bus needed),
// MemoryCanChannel (tests). After open(), every method but flush() is RT-safe: noexcept,
// no allocation, never blocking; a full queue drops the frame and counts it.
#pragma once

#include <atomic>
#include <cstdint>
#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::hal {

struct CanFrame {
  static constexpr std::uint8_t kExtended = 1u << 0;  // 29-bit id
  static constexpr std::uint8_t kFd = 1u << 1;        // CAN FD frame (len up to 64)
  static constexpr std::uint8_t kBrs = 1u << 2;       // FD bit-rate switch
  static constexpr std::uint8_t kRemote = 1u << 3;    // RTR (classic only)

  std::uint32_t id = 0;
  std::uint8_t len = 0;    // bytes of payload (0..8 classic, 0..64 FD)
  std::uint8_t flags = 0;
  std::uint8_t data[64]{};

  bool extended() const noexcept { return (flags & kExtended) != 0; }
  bool fd() const noexcept { return (flags & kFd) != 0; }
  bool remote() const noexcept { return (flags & kRemote) != 0; }
};

enum class CanSendResult : std::uint8_t {
  kSent = 0,
  kDropped,  // queue/buffer full (EAGAIN, ENOBUFS, log ring full) or bus off: counted
  kError,    // anything else (interface down, frame too long for the channel): counted
};

// ISO 11898 fault confinement as seen from error frames.
enum class CanBusState : std::uint8_t { kActive = 0, kPassive = 1, kBusOff = 2 };

constexpr const char* to_string(CanBusState s) noexcept {
  switch (s) {
    case CanBusState::kActive: return "error-active";
    case CanBusState::kPassive: return "error-passive";
    case CanBusState::kBusOff: return "bus-off";
  }
  return "?";
}

// Written by the RT thread that owns the channel, read by anyone (relaxed: statistics).
struct CanChannelCounters {
  std::atomic<std::uint64_t> tx_frames{0};
  std::atomic<std::uint64_t> tx_dropped{0};
  std::atomic<std::uint64_t> tx_errors{0};
  std::atomic<std::uint64_t> rx_frames{0};
  std::atomic<std::uint64_t> error_frames{0};
  // SocketCAN: times the channel was bound again to an interface that had gone (deleted,
  // e.g. a USB adapter unplugged) and came back. Written by flush()'s (non-RT) caller only.
  std::atomic<std::uint64_t> rebinds{0};
  std::atomic<std::uint8_t> bus_state{0};  // CanBusState

  static void bump(std::atomic<std::uint64_t>& c) noexcept {
    rt::add_single_writer(c);
  }
};

class CanChannel {
 public:
  virtual ~CanChannel() = default;
  CanChannel() = default;
  CanChannel(const CanChannel&) = delete;
  CanChannel& operator=(const CanChannel&) = delete;

  // Sends one frame without blocking. t_ns is the sender's clock (CLOCK_MONOTONIC or the
  // virtual clock); only the log channel uses it, for its timestamps.
  virtual CanSendResult send(const CanFrame& frame, std::int64_t t_ns) noexcept = 0;
  // Takes one received data frame, if any, without blocking; error frames are folded into
  // bus_state() and never returned.
  virtual bool receive(CanFrame& /*out*/) noexcept { return false; }
  virtual CanBusState bus_state() const noexcept {
    return static_cast<CanBusState>(counters_.bus_state.load(std::memory_order_relaxed));
  }
  // True when the channel carries CAN FD frames (SocketCAN: MTU 72 and allowed by config).
  virtual bool fd_enabled() const noexcept { return false; }
  // Non-RT, called periodically: writes out buffered data (the log channel); SocketCAN binds
  // again to an interface that had gone and is back. No-op elsewhere.
  virtual void flush() {}
  // True while the channel's interface is gone (SocketCAN: deleted or unplugged): every send
  // fails and is counted until flush() finds the interface again.
  virtual bool detached() const noexcept { return false; }
  virtual const char* name() const noexcept = 0;

  const CanChannelCounters& counters() const noexcept { return counters_; }

 protected:
  CanChannelCounters counters_;
};

}  // namespace sempose::hal
