// Poses as CSV (README: Replay and recording: frame,t_ns,x_px,y_px,phi_deg,score,status[,target]).
// publish() (RT) copies the pose into a preallocated single-producer ring; the non-RT thread
// calls write_pending() to format and write them. A full ring drops and counts, never blocks.
#pragma once

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include "sempose/pipeline/pose_sink.hpp"
#include "sempose/rt/result.hpp"
#include "sempose/rt/spsc_buffer.hpp"

namespace sempose::pipeline {

class CsvPoseSink final : public PoseSink {
 public:
  // Setup: opens the file ("-": standard output) and writes the header. capacity: poses
  // buffered (power of two).
  CsvPoseSink(std::string path, std::size_t capacity, bool with_target_column);
  ~CsvPoseSink() override;
  rt::Status open();
  // Setup, in two steps (sempose run, so that a run refused on a later output has emptied
  // nothing): open_keeping() creates the file or opens it as it is, truncating nothing;
  // begin() then empties it and writes the header.
  rt::Status open_keeping();
  rt::Status begin();

  PublishResult publish(const PoseRecord& pose, std::int64_t t_now_ns) noexcept override;
  // Non-RT: writes everything published so far.
  void write_pending();
  void flush() override { write_pending(); }

  // Non-RT: writes what is pending and closes; false when any write failed.
  bool close();

  std::uint64_t written() const noexcept { return written_; }
  // Failed writes (a full disk, an I/O error, the file deleted while open: ENOENT, poses the
  // writer fell too far behind to keep: ENOBUFS, counted in dropped()): how often, how many
  // pose lines were lost in writing (lost_lines() + dropped() is every missing line), and the
  // last errno (0: none).
  std::uint64_t write_errors() const noexcept { return write_errors_; }
  std::uint64_t lost_lines() const noexcept { return lost_lines_; }
  int last_errno() const noexcept { return last_errno_; }
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::string path_;
  bool with_target_;
  rt::SpscBuffer<PoseRecord> ring_;  // output stage → writer thread
  std::atomic<std::uint64_t> dropped_{0};
  std::FILE* file_ = nullptr;
  std::uint64_t written_ = 0;
  std::uint64_t write_errors_ = 0;
  std::uint64_t lost_lines_ = 0;
  int last_errno_ = 0;
  std::uint64_t dropped_seen_ = 0;  // dropped() already reported as a write error
  bool regular_file_ = false;       // can be cut back to good_offset_ after a failed write
  long good_offset_ = 0;            // end of the last whole line written
  bool header_written_ = false;
  // begin() ran: the file is ours to write. Opened by open_keeping() and dropped before begin()
  // (a refused run), nothing is written: its header went over the last run's first bytes.
  bool begun_ = false;
  bool deleted_noted_ = false;      // the file was unlinked while open (noted once when idle)
  void note_error(int err, std::uint64_t lines);
};

// Fans one pose out to several sinks (e.g. CSV for validation + CAN). Commands come from
// the first sink that has one.
class TeePoseSink final : public PoseSink {
 public:
  TeePoseSink(PoseSink* a, PoseSink* b) noexcept : a_(a), b_(b) {}
  PublishResult publish(const PoseRecord& pose, std::int64_t t_now_ns) noexcept override {
    const PublishResult ra = a_->publish(pose, t_now_ns);
    const PublishResult rb = b_->publish(pose, t_now_ns);
    return ra == PublishResult::kSent ? rb : ra;
  }
  void service(const PipelineStatus& s, std::int64_t t) noexcept override {
    a_->service(s, t);
    b_->service(s, t);
  }
  bool next_command(Command& out) noexcept override { return a_->next_command(out) || b_->next_command(out); }
  void flush() override {
    a_->flush();
    b_->flush();
  }

 private:
  PoseSink* a_;
  PoseSink* b_;
};

}  // namespace sempose::pipeline
