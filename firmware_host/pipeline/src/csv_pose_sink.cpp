#include "sempose/pipeline/csv_pose_sink.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::pipeline {
CsvPoseSink::CsvPoseSink(std::string path, std::size_t capacity, bool with_target_column)
    : path_(std::move(path)), with_target_(with_target_column) {
  ring_.allocate(std::max<std::size_t>(16, capacity));
}

CsvPoseSink::~CsvPoseSink() { close(); }

bool CsvPoseSink::close() {
  if (file_ == nullptr) return write_errors_ == 0;
  write_pending();
  // stdout ("-") is flushed, not closed: the process still prints its report after the poses.
  if ((file_ == stdout ? std::fflush(file_) : std::fclose(file_)) != 0) note_error(errno, 0);
  file_ = nullptr;
  return write_errors_ == 0;
}

void CsvPoseSink::note_error(int err, std::uint64_t lines) {
  ++write_errors_;
  lost_lines_ += lines;
  last_errno_ = err;
}

rt::Status CsvPoseSink::open() {
  rt::Status st = open_keeping();
  return st ? begin() : st;
}

rt::Status CsvPoseSink::open_keeping() {
  // "-" is standard output, as for any Unix tool that writes a stream (`replay --out - | …`).
  if (path_ == "-") {
    file_ = stdout;
    return rt::Status::success();
  }
  const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  file_ = fd >= 0 ? ::fdopen(fd, "w") : nullptr;  // "w" on an open descriptor truncates nothing
  if (file_ == nullptr) {
    const int err = errno;
    if (fd >= 0) ::close(fd);
    return rt::Status::failure("output.poses_csv: cannot create '" + path_ + "': " + std::strerror(err));
  }
  return rt::Status::success();
}

rt::Status CsvPoseSink::begin() {
  if (file_ == nullptr) return rt::Status::failure("output.poses_csv: '" + path_ + "' is not open");
  // A regular file is emptied now (a device or a pipe has nothing to empty), and can be cut back
  // to its last whole line after a failed write (below); a pipe or terminal cannot and need not
  // (a pipe takes a line whole or fails with EPIPE).
  // Standard output is the caller's stream, not ours to empty or cut back: the shell's `>` has
  // emptied it already, `>>` asks for the lines after what is there (found probing: `replay
  // --out - >> FILE` emptied FILE, exit 0), and its offset is not where an appending write lands.
  struct stat st{};
  regular_file_ = file_ != stdout && ::fstat(::fileno(file_), &st) == 0 && S_ISREG(st.st_mode);
  if (regular_file_ && ::ftruncate(::fileno(file_), 0) != 0)
    return rt::Status::failure("output.poses_csv: cannot empty '" + path_ + "': " + std::strerror(errno));
  good_offset_ = regular_file_ ? std::ftell(file_) : 0;
  header_written_ = false;
  begun_ = true;
  write_pending();  // the header, now: a full disk shows at once
  return rt::Status::success();
}

PublishResult CsvPoseSink::publish(const PoseRecord& pose, std::int64_t t_now_ns) noexcept {
  (void)t_now_ns;
  if (!ring_.try_push(pose)) {
    rt::add_single_writer(dropped_);
    return PublishResult::kDropped;
  }
  return PublishResult::kSent;
}

void CsvPoseSink::write_pending() {
  if (file_ == nullptr || !begun_) return;
  // Poses the RT side could not keep (ring full: this thread fell behind) are lost lines
  // too: counted in dropped() and reported as a write error, never silently missing.
  const std::uint64_t dropped_now = dropped();
  if (dropped_now != dropped_seen_) {
    ++write_errors_;
    last_errno_ = ENOBUFS;
    dropped_seen_ = dropped_now;
  }
  // The header goes out with the first round that can be written (a disk full at open
  // must not leave a file of pose lines without one).
  const bool header = !header_written_;
  if (header) {
    std::fprintf(file_, "frame,t_ns,x_px,y_px,phi_deg,score,status%s,scale,sigma_x_px,sigma_y_px,sigma_phi_deg,sigma_scale,angle_order\n",
                 with_target_ ? ",target" : "");
  }
  std::uint64_t lines = 0;
  for (auto batch = ring_.readable(); !batch.empty(); batch = ring_.readable()) {
    for (const PoseRecord& p : batch) {
      // t_ns: when the beam passed the target (the time the pose is valid for; the scan's end
      // when not known).
      std::fprintf(file_, "%llu,%lld,%.4f,%.4f,%.4f,%.5f,%s", static_cast<unsigned long long>(p.frame_seq),
                   static_cast<long long>(p.t_beam_ns != 0 ? p.t_beam_ns : p.t_scan_end_ns), p.x_px, p.y_px, p.phi_deg, static_cast<double>(p.score),
                   pose::to_string(p.state));
      if (with_target_) std::fprintf(file_, ",%u", static_cast<unsigned>(p.target));
      std::fprintf(file_, ",%.4f", p.target_scale);  // the target's size over its pattern's
      // 1σ of the measured pose (0: not measured, e.g. a start-search frame).
      std::fprintf(file_, ",%.5f,%.5f,%.5f,%.6f", p.sigma_x_px, p.sigma_y_px, p.sigma_phi_deg, p.sigma_scale);
      // phi_deg is known modulo 360°/angle_order (a pattern that looks the same turned by that).
      std::fprintf(file_, ",%u", static_cast<unsigned>(p.angle_order));
      std::fputc('\n', file_);
      ++lines;
    }
    ring_.consume(batch.size());
  }
  // A full disk or an I/O error is found at the flush: the lines of this round are counted
  // as lost (stdio discards what it could not write), the error is kept for the summary.
  // The kernel may have taken part of the round (up to the last free block, mid-line): the
  // file is cut back to its last whole line, so once space returns the next lines do not
  // follow a torn one (measured on a full tmpfs: a 4 KiB-aligned half line glued to the
  // next round's first line).
  if (std::fflush(file_) != 0 || std::ferror(file_)) {
    note_error(errno, lines);
    std::clearerr(file_);
    if (regular_file_ && ::ftruncate(::fileno(file_), good_offset_) == 0) std::fseek(file_, good_offset_, SEEK_SET);
    return;
  }
  // Lines written into a file that was deleted meanwhile reach nobody: lost, and said so.
  struct stat st{};
  if (regular_file_ && ::fstat(::fileno(file_), &st) == 0 && st.st_nlink == 0) {
    if (lines > 0 || header || !deleted_noted_) note_error(ENOENT, lines);
    deleted_noted_ = true;
    return;
  }
  header_written_ = true;
  written_ += lines;
  if (regular_file_) good_offset_ = std::ftell(file_);
}

}  // namespace sempose::pipeline
