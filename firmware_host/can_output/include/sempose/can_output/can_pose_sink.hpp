// Poses and heartbeats as CAN frames, commands from the controller (ipc/ protocol) over any
// hal::CanChannel (SocketCAN, candump log, memory). All PoseSink methods are RT-safe:
// noexcept, no allocation, never blocking; failures are counted.
//
// Commands are read in service(), i.e. on the output stage's thread: it already owns the
// channel (one socket, one reader, no lock, no extra thread), and it runs every cycle, so a
// command waits at most one output cycle. Valid ones go into a small SPSC ring that
// next_command() drains (from the output stage or one other thread); invalid ones are counted
// and dropped.
#pragma once

#include <atomic>
#include <cstdint>

#include "sempose/hal/can_channel.hpp"
#include "sempose/ipc/protocol.hpp"
#include "sempose/pipeline/pose_sink.hpp"
#include "sempose/rt/spsc_ring.hpp"
#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::can_output {

struct CanSinkOptions {
  ipc::IdMap ids = ipc::IdMap::with_base(ipc::kDefaultBaseId);
  std::int64_t heartbeat_period_ns = 100'000'000;  // 10 Hz
  int max_commands_per_cycle = 8;
};

// Readable from any thread (relaxed atomics; single writer each).
struct CanSinkCounters {
  std::atomic<std::uint64_t> poses_sent{0};
  std::atomic<std::uint64_t> poses_dropped{0};     // at least one frame of the pose not sent
  std::atomic<std::uint64_t> heartbeats_sent{0};
  std::atomic<std::uint64_t> heartbeats_dropped{0};
  std::atomic<std::uint64_t> commands_accepted{0};
  std::atomic<std::uint64_t> bad_commands{0};      // failed validation: counted, never acted on
  std::atomic<std::uint64_t> commands_overflowed{0};  // valid, but the command ring was full
  std::atomic<std::uint64_t> non_command_frames{0};   // other ids seen on the bus (ignored)
  std::atomic<std::uint8_t> last_command_seq{0};
  std::atomic<std::uint8_t> last_bad_reason{0};    // ipc::CommandCheck of the last bad frame
};

class CanPoseSink final : public pipeline::PoseSink {
 public:
  CanPoseSink(hal::CanChannel& channel, const CanSinkOptions& options) noexcept;

  pipeline::PublishResult publish(const pipeline::PoseRecord& pose, std::int64_t t_now_ns) noexcept override;
  void service(const pipeline::PipelineStatus& status, std::int64_t t_now_ns) noexcept override;
  bool next_command(pipeline::Command& out) noexcept override;
  // Non-RT: writes the log channel's buffer. Safe to call periodically while running.
  void flush() override { channel_.flush(); }

  const CanSinkCounters& counters() const noexcept { return counters_; }
  const hal::CanChannel& channel() const noexcept { return channel_; }
  bool fd() const noexcept { return fd_; }
  const CanSinkOptions& options() const noexcept { return options_; }

  // Pure helpers (also used by tests).
  static ipc::PoseValues to_values(const pipeline::PoseRecord& pose, std::int64_t t_now_ns) noexcept;
  static bool to_command(const ipc::WireCommand& wire, pipeline::Command& out) noexcept;

 private:
  void send_heartbeat(const pipeline::PipelineStatus& status, std::int64_t t_now_ns) noexcept;
  void read_commands() noexcept;
  static void bump(std::atomic<std::uint64_t>& c) noexcept {
    rt::add_single_writer(c);
  }

  hal::CanChannel& channel_;
  CanSinkOptions options_;
  bool fd_ = false;
  std::int64_t next_heartbeat_ns_ = 0;
  bool heartbeat_started_ = false;
  std::uint8_t heartbeat_counter_ = 0;
  rt::SpscRing<pipeline::Command, 16> commands_;
  CanSinkCounters counters_;
};

}  // namespace sempose::can_output
