#include "sempose/pipeline/csv_pose_sink.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::pipeline {
CsvPoseSink::CsvPoseSink(std::string path, std::size_t capacity, bool with_target_column)
    : path_(std::move(path)), with_target_(with_target_column) {
  ring_.allocate(std::max<std::size_t>(16, capacity));
}

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
  if (!ring_.try_push(pose)) {
    rt::add_single_writer(dropped_);
    return PublishResult::kDropped;
  }
  return PublishResult::kSent;
}

void CsvPoseSink::write_pending() {
  if (file_ == nullptr) return;
  for (auto batch = ring_.readable(); !batch.empty(); batch = ring_.readable()) {
    for (const PoseRecord& p : batch) {
      // t_ns: when the frame's scan ended (the time the pose is valid for).
      std::fprintf(file_, "%llu,%lld,%.4f,%.4f,%.4f,%.5f,%s", static_cast<unsigned long long>(p.frame_seq),
                   static_cast<long long>(p.t_scan_end_ns), p.x_px, p.y_px, p.phi_deg, static_cast<double>(p.score),
                   pose::to_string(p.state));
      if (with_target_) std::fprintf(file_, ",%u", static_cast<unsigned>(p.target));
      std::fputc('\n', file_);
      ++written_;
    }
    ring_.consume(batch.size());
  }
  std::fflush(file_);
}

}  // namespace sempose::pipeline
