#include "sempose/pipeline/csv_pose_sink.hpp"

#include <cerrno>
#include <cstring>
#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::pipeline {
namespace {
std::size_t round_pow2(std::size_t n) {
  std::size_t p = 16;
  while (p < n) p <<= 1;
  return p;
}
}  // namespace

CsvPoseSink::CsvPoseSink(std::string path, std::size_t capacity, bool with_target_column)
    : path_(std::move(path)),
      capacity_(round_pow2(capacity)),
      mask_(capacity_ - 1),
      with_target_(with_target_column),
      ring_(new PoseRecord[capacity_]) {}

CsvPoseSink::~CsvPoseSink() {
  if (file_ != nullptr) {
    write_pending();
    std::fclose(file_);
  }
}

rt::Status CsvPoseSink::open() {
  file_ = std::fopen(path_.c_str(), "w");
  if (file_ == nullptr) {
    return rt::Status::failure("output.poses_csv: cannot create '" + path_ + "': " + std::strerror(errno));
  }
  std::fprintf(file_, "frame,t_ns,x_px,y_px,phi_deg,score,status%s\n", with_target_ ? ",target" : "");
  return rt::Status::success();
}

PublishResult CsvPoseSink::publish(const PoseRecord& pose, std::int64_t t_now_ns) noexcept {
  (void)t_now_ns;
  const std::size_t tail = tail_.load(std::memory_order_relaxed);
  if (tail - head_.load(std::memory_order_acquire) >= capacity_) {
    rt::add_single_writer(dropped_);
    return PublishResult::kDropped;
  }
  ring_[tail & mask_] = pose;
  tail_.store(tail + 1, std::memory_order_release);
  return PublishResult::kSent;
}

void CsvPoseSink::write_pending() {
  if (file_ == nullptr) return;
  const std::size_t tail = tail_.load(std::memory_order_acquire);
  std::size_t head = head_.load(std::memory_order_relaxed);
  for (; head != tail; ++head) {
    const PoseRecord& p = ring_[head & mask_];
    // t_ns: when the frame's scan ended (the time the pose is valid for).
    std::fprintf(file_, "%llu,%lld,%.4f,%.4f,%.4f,%.5f,%s", static_cast<unsigned long long>(p.frame_seq),
                 static_cast<long long>(p.t_scan_end_ns), p.x_px, p.y_px, p.phi_deg, static_cast<double>(p.score),
                 pose::to_string(p.state));
    if (with_target_) std::fprintf(file_, ",%u", static_cast<unsigned>(p.target));
    std::fputc('\n', file_);
    ++written_;
  }
  head_.store(head, std::memory_order_release);
  std::fflush(file_);
}

}  // namespace sempose::pipeline
