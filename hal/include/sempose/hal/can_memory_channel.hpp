// An in-memory CAN channel for tests and offline runs (Lely's "virtual" channel): sent frames
// are kept in a preallocated buffer, frames to receive are queued by the test. RT-safe after
// construction; inject()/sent() are for the (single-threaded) test.
#pragma once

#include <cstddef>
#include <vector>

#include "sempose/hal/can_channel.hpp"

namespace sempose::hal {

class MemoryCanChannel final : public CanChannel {
 public:
  explicit MemoryCanChannel(std::size_t capacity = 4096, bool fd = false)
      : sent_(capacity), rx_(capacity), fd_(fd) {}

  CanSendResult send(const CanFrame& frame, std::int64_t t_ns) noexcept override {
    if ((frame.fd() && !fd_) || frame.len > (frame.fd() ? 64 : 8)) {
      CanChannelCounters::bump(counters_.tx_errors);
      return CanSendResult::kError;
    }
    if (fail_sends_ || sent_count_ == sent_.size()) {
      CanChannelCounters::bump(counters_.tx_dropped);
      return CanSendResult::kDropped;
    }
    sent_[sent_count_] = frame;
    last_t_ns_ = t_ns;
    ++sent_count_;
    CanChannelCounters::bump(counters_.tx_frames);
    return CanSendResult::kSent;
  }
  bool receive(CanFrame& out) noexcept override {
    if (rx_head_ == rx_tail_) return false;
    out = rx_[rx_head_++ % rx_.size()];
    CanChannelCounters::bump(counters_.rx_frames);
    return true;
  }
  bool fd_enabled() const noexcept override { return fd_; }
  const char* name() const noexcept override { return "memory"; }

  // Test side.
  void inject(const CanFrame& f) { rx_[rx_tail_++ % rx_.size()] = f; }
  std::size_t sent_count() const noexcept { return sent_count_; }
  const CanFrame& sent(std::size_t i) const { return sent_.at(i); }
  void clear_sent() noexcept { sent_count_ = 0; }
  void set_fail_sends(bool fail) noexcept { fail_sends_ = fail; }
  void set_bus_state(CanBusState s) noexcept {
    counters_.bus_state.store(static_cast<std::uint8_t>(s), std::memory_order_relaxed);
  }
  std::int64_t last_t_ns() const noexcept { return last_t_ns_; }

 private:
  std::vector<CanFrame> sent_;
  std::vector<CanFrame> rx_;
  std::size_t sent_count_ = 0;
  std::size_t rx_head_ = 0;
  std::size_t rx_tail_ = 0;
  bool fd_ = false;
  bool fail_sends_ = false;
  std::int64_t last_t_ns_ = 0;
};

}  // namespace sempose::hal
