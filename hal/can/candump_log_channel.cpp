// candump -l log channel. See can_candump_log.hpp.
#include "sempose/hal/can_candump_log.hpp"

#include "sempose/rt/single_writer_counter.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>

namespace sempose::hal {
namespace {

constexpr char kHex[] = "0123456789ABCDEF";

char* put_decimal(char* p, std::uint64_t v, int min_digits) noexcept {
  char tmp[24];
  int n = 0;
  do {
    tmp[n++] = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v != 0 && n < 24);
  while (n < min_digits && n < 24) tmp[n++] = '0';
  while (n > 0) *p++ = tmp[--n];
  return p;
}

char* put_hex(char* p, std::uint32_t v, int digits) noexcept {
  for (int i = digits - 1; i >= 0; --i) *p++ = kHex[(v >> (4 * i)) & 0xF];
  return p;
}

}  // namespace

std::size_t CandumpLogChannel::format_line(const CanFrame& f, std::int64_t t_ns, const char* channel,
                                           char* out) noexcept {
  char* p = out;
  const std::uint64_t t = t_ns < 0 ? 0 : static_cast<std::uint64_t>(t_ns);
  *p++ = '(';
  p = put_decimal(p, t / 1'000'000'000u, 10);
  *p++ = '.';
  p = put_decimal(p, (t % 1'000'000'000u) / 1000u, 6);
  *p++ = ')';
  *p++ = ' ';
  for (int i = 0; channel[i] != '\0' && i < 16; ++i) *p++ = channel[i];
  *p++ = ' ';
  p = f.extended() ? put_hex(p, f.id & 0x1FFFFFFFu, 8) : put_hex(p, f.id & 0x7FFu, 3);
  *p++ = '#';
  const std::uint8_t max_len = f.fd() ? 64 : 8;
  const std::uint8_t len = f.len > max_len ? max_len : f.len;
  if (f.fd()) {
    *p++ = '#';
    *p++ = kHex[(f.flags & CanFrame::kBrs) ? 1 : 0];  // candump's FD flags digit (CANFD_BRS = 1)
  } else if (f.remote()) {
    *p++ = 'R';
    *p++ = '\n';
    return static_cast<std::size_t>(p - out);
  }
  for (std::uint8_t i = 0; i < len; ++i) {
    *p++ = kHex[f.data[i] >> 4];
    *p++ = kHex[f.data[i] & 0xF];
  }
  *p++ = '\n';
  return static_cast<std::size_t>(p - out);
}

std::unique_ptr<CandumpLogChannel> CandumpLogChannel::open(const CandumpLogOptions& o, rt::Status& status) {
  if (o.path.empty()) {
    status = rt::Status::failure("can.log_file: empty path (set a file for the candump log)");
    return nullptr;
  }
  if (o.channel_name.empty() || o.channel_name.size() > 15 || o.channel_name.find_first_of(" \t\n#()") != std::string::npos) {
    status = rt::Status::failure("can.log_channel: '" + o.channel_name + "' must be 1..15 characters without spaces, '#' or parentheses");
    return nullptr;
  }
  std::unique_ptr<CandumpLogChannel> ch(new CandumpLogChannel());
  ch->path_ = o.path;
  ch->channel_ = o.channel_name;
  ch->fd_ = o.fd;
  ch->wall_clock_ = o.wall_clock;
  // At least 4 KiB and four lines; a power of two.
  ch->ring_.allocate(std::max<std::size_t>({4096, kMaxLine * 4, o.buffer_bytes}));
  ch->file_ = ::open(o.path.c_str(), O_WRONLY | O_CREAT | (o.keep_existing ? 0 : O_TRUNC) | O_CLOEXEC, 0644);
  if (ch->file_ < 0) {
    status = rt::Status::failure("can.log_file '" + o.path + "': cannot create: " + std::strerror(errno));
    return nullptr;
  }
  struct stat st{};
  ch->regular_file_ = ::fstat(ch->file_, &st) == 0 && S_ISREG(st.st_mode);
  status = rt::Status::success();
  return ch;
}

CandumpLogChannel::~CandumpLogChannel() {
  flush();
  if (file_ >= 0) ::close(file_);
}

CanSendResult CandumpLogChannel::send(const CanFrame& f, std::int64_t t_ns) noexcept {
  if ((f.fd() && !fd_) || f.len > (f.fd() ? 64 : 8)) {
    CanChannelCounters::bump(counters_.tx_errors);
    return CanSendResult::kError;
  }
  if (wall_clock_) {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);  // vDSO: no syscall
    t_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  }
  char line[kMaxLine];
  const std::size_t n = format_line(f, t_ns, channel_.c_str(), line);
  if (!ring_.try_push(line, n)) {
    CanChannelCounters::bump(counters_.tx_dropped);
    rt::add_single_writer(ring_full_, n);
    return CanSendResult::kDropped;
  }
  CanChannelCounters::bump(counters_.tx_frames);
  return CanSendResult::kSent;
}

void CandumpLogChannel::flush() {
  std::lock_guard<std::mutex> lock(flush_mutex_);
  if (file_ < 0) return;
  std::uint64_t flushed = 0;
  for (auto pending = ring_.readable(); !pending.empty(); pending = ring_.readable()) {
    if (skip_to_line_end_) {  // the rest of a line tear_back() cut from the file: dropped, counted
      const char* nl = static_cast<const char*>(std::memchr(pending.data(), '\n', pending.size()));
      const std::size_t n = nl ? static_cast<std::size_t>(nl - pending.data()) + 1 : pending.size();
      ring_.consume(n);
      lost_.fetch_add(n, std::memory_order_relaxed);
      skip_to_line_end_ = nl == nullptr;
      continue;
    }
    const ssize_t w = ::write(file_, pending.data(), pending.size());
    if (w < 0) {
      if (errno == EINTR) continue;
      // Disk full, I/O error: counted and reported (summary, heartbeat, exit code). The data
      // stays in the ring for the next flush (the error may pass); once the ring is full,
      // send() counts every frame it cannot keep as dropped.
      write_errors_.fetch_add(1, std::memory_order_relaxed);
      last_errno_.store(errno, std::memory_order_relaxed);
      tear_back();
      break;
    }
    const auto n = static_cast<std::size_t>(w);
    for (std::size_t i = n; i > 0; --i) {
      if (pending.data()[i - 1] == '\n') {
        whole_end_ = file_end_ + i;
        break;
      }
    }
    file_end_ += n;
    ring_.consume(n);
    written_.fetch_add(n, std::memory_order_relaxed);
    flushed += n;
    if (n < pending.size()) {  // a short write (a full disk takes what fits): the rest next time
      tear_back();
      break;
    }
  }
  // Written into a file that was deleted meanwhile (an operator cleaning the log folder):
  // the bytes reach nobody. Counted as lost and as a write error, not taken as written.
  struct stat st{};
  if (flushed > 0 && ::fstat(file_, &st) == 0 && st.st_nlink == 0) {
    write_errors_.fetch_add(1, std::memory_order_relaxed);
    last_errno_.store(ENOENT, std::memory_order_relaxed);
    lost_.fetch_add(flushed, std::memory_order_relaxed);
  }
}

// A write that failed or fell short may have left the file ending inside a line (found probing:
// the log on a full tmpfs ended in "(000", where the poses' CSV is cut back to its last whole
// line). A regular file is cut back to its last whole line, the cut bytes counted lost, and the
// rest of that line, still in the ring, dropped when the next flush reaches it.
void CandumpLogChannel::tear_back() {
  if (!regular_file_ || file_end_ == whole_end_) return;
  if (::ftruncate(file_, static_cast<off_t>(whole_end_)) != 0 || ::lseek(file_, static_cast<off_t>(whole_end_), SEEK_SET) < 0) return;
  const std::uint64_t torn = file_end_ - whole_end_;
  written_.fetch_sub(torn, std::memory_order_relaxed);
  lost_.fetch_add(torn, std::memory_order_relaxed);
  file_end_ = whole_end_;
  skip_to_line_end_ = true;
}

}  // namespace sempose::hal
