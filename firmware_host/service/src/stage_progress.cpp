#include "sempose/service/stage_progress.hpp"

#include <cstdio>

namespace sempose::service {

ProgressMonitor::ProgressMonitor(std::int64_t stall_timeout_ns, std::int64_t start_ns) noexcept
    : stages_{pipeline::ProgressWatch(stall_timeout_ns, start_ns), pipeline::ProgressWatch(stall_timeout_ns, start_ns),
              pipeline::ProgressWatch(stall_timeout_ns, start_ns)} {}

std::uint8_t ProgressMonitor::update(std::int64_t now_ns, const StageCounts& c, bool expect_progress) noexcept {
  const std::array<std::uint64_t, 3> now_count{c.frames, c.poses, c.published};
  stalled_ = 0;
  for (int s = 0; s < 3; ++s) {
    if (stages_[s].stalled(now_count[s], now_ns, expect_progress)) stalled_ |= static_cast<std::uint8_t>(1u << s);
  }
  return stalled_;
}

std::string describe_stall(std::uint8_t bits, const ProgressMonitor& m, std::int64_t now_ns) {
  static constexpr const char* kWhat[3] = {"acquisition (no frame scanned", "correlation (no pose made",
                                           "output (no pose published"};
  std::string out;
  for (int s = 0; s < 3; ++s) {
    if ((bits & (1u << s)) == 0) continue;
    char buf[96];
    std::snprintf(buf, sizeof buf, "%s%s for %.1f s)", out.empty() ? "" : ", ", kWhat[s], m.idle_ns(s, now_ns) * 1e-9);
    out += buf;
  }
  return out;
}

}  // namespace sempose::service
