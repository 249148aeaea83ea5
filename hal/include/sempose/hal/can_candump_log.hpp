// A CAN channel that writes every frame as a candump -l log line instead of sending it:
//   (0000012345.678901) can0 123#DEADBEEF        classic (3 hex digits id; 8 if extended)
//   (0000012345.678901) can0 102##0<128 hex>     CAN FD (## + one flags digit, as candump)
// so canplayer can replay it onto a bus and python-can's CanutilsLogReader reads it.
//
// RT-safe: send() formats into a preallocated single-producer/single-consumer byte ring;
// flush(), called by a non-RT thread (periodically and at shutdown), write()s the ring to
// the file. A full ring drops the line and counts it (tx_dropped); no file I/O ever runs
// on the sending thread.
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "sempose/hal/can_channel.hpp"
#include "sempose/rt/result.hpp"
#include "sempose/rt/spsc_buffer.hpp"

namespace sempose::hal {

struct CandumpLogOptions {
  std::string path;
  std::string channel_name = "can0";      // the interface name written on each line
  std::size_t buffer_bytes = 1u << 20;    // rounded up to a power of two
  bool wall_clock = false;  // false: timestamps from the sender's clock (t_ns); true: CLOCK_REALTIME
  bool fd = false;          // accept CAN FD frames (the log can hold them; replay needs an FD bus)
  // Opened without truncating: the caller empties the file once every output of the run has
  // opened (sempose run: a run refused on a later output must not have emptied this one).
  bool keep_existing = false;
};

class CandumpLogChannel final : public CanChannel {
 public:
  // Setup: creates/truncates the file (keep_existing: creates, truncates nothing). nullptr +
  // message naming the path and errno text.
  static std::unique_ptr<CandumpLogChannel> open(const CandumpLogOptions& options, rt::Status& status);
  ~CandumpLogChannel() override;  // flushes and closes

  CanSendResult send(const CanFrame& frame, std::int64_t t_ns) noexcept override;
  bool fd_enabled() const noexcept override { return fd_; }
  void flush() override;
  const char* name() const noexcept override { return path_.c_str(); }

  // Formats one line (with '\n') into out (>= kMaxLine bytes); returns its length. Pure.
  static constexpr std::size_t kMaxLine = 224;
  static std::size_t format_line(const CanFrame& frame, std::int64_t t_ns, const char* channel,
                                 char* out) noexcept;
  std::uint64_t bytes_written() const noexcept { return written_.load(std::memory_order_relaxed); }
  // Failed write(2) calls (full disk, I/O error), the last errno, and the bytes still
  // waiting in the ring (after the last flush at exit: bytes that never reached the file).
  std::uint64_t write_errors() const noexcept { return write_errors_.load(std::memory_order_relaxed); }
  int last_errno() const noexcept { return last_errno_.load(std::memory_order_relaxed); }
  std::uint64_t bytes_pending() const noexcept { return ring_.pending(); }
  // Bytes written into the file after it was deleted (ENOENT in last_errno()), and the bytes of
  // a line a failed write tore (cut from the file, the rest dropped from the ring): lost too.
  std::uint64_t bytes_lost_to_deleted_file() const noexcept { return lost_.load(std::memory_order_relaxed); }
  // Bytes of lines send() dropped because the ring was full (can.log_buffer_bytes too small for
  // what comes between two flushes): lines the log lacks, as the CSV's ring-full poses are. They
  // were counted only as tx_dropped, a busy bus's counter, and the run ended exit 0 (hostile
  // round 11).
  std::uint64_t bytes_dropped_ring_full() const noexcept { return ring_full_.load(std::memory_order_relaxed); }

 private:
  CandumpLogChannel() = default;

  std::string path_;
  std::string channel_;
  int file_ = -1;
  // A regular file ends in whole lines: where its last whole line ends, where writing is, and
  // whether the ring's head is the rest of a line cut from the file (tear_back()).
  bool regular_file_ = false;
  std::uint64_t file_end_ = 0, whole_end_ = 0;
  bool skip_to_line_end_ = false;
  void tear_back();
  bool fd_ = false;
  bool wall_clock_ = false;
  rt::SpscBuffer<char> ring_;  // send (RT) → flush (non-RT)
  std::atomic<std::uint64_t> written_{0};
  std::atomic<std::uint64_t> write_errors_{0};
  std::atomic<int> last_errno_{0};
  std::atomic<std::uint64_t> lost_{0};
  std::atomic<std::uint64_t> ring_full_{0};  // written by send() only
  std::mutex flush_mutex_;  // non-RT side only: two non-RT callers of flush() never interleave
};

}  // namespace sempose::hal
