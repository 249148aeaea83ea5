// The stall rule behind the watchdog: each RT stage has a counter that only moves when the
// stage did its job (acquisition: frames scanned; correlation: poses made; output: poses
// published, sent or dropped by a full bus). A stage whose counter has not moved for the
// stall timeout while scanning is enabled is stalled — pipeline::ProgressWatch, the rule the
// source's stall watchdog uses too. Pure and clock-free (times are passed in), so the rule is
// tested without threads.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "sempose/pipeline/stall_watchdog.hpp"

namespace sempose::service {

enum StageBit : std::uint8_t { kAcquisitionStalled = 1, kCorrelationStalled = 2, kOutputStalled = 4 };

struct StageCounts {
  std::uint64_t frames = 0;     // acquisition
  std::uint64_t poses = 0;      // correlation
  std::uint64_t published = 0;  // output
};

class ProgressMonitor {
 public:
  ProgressMonitor(std::int64_t stall_timeout_ns, std::int64_t start_ns) noexcept;
  // Takes a new sample. expect_progress is false while the pipeline idles on purpose (a STOP
  // command): nothing is stalled then and every stage's clock restarts. Returns the stall bits.
  std::uint8_t update(std::int64_t now_ns, const StageCounts& counts, bool expect_progress) noexcept;
  std::uint8_t stalled() const noexcept { return stalled_; }
  // ns since the given stage (0 acquisition, 1 correlation, 2 output) last moved.
  std::int64_t idle_ns(int stage, std::int64_t now_ns) const noexcept { return stages_[stage].idle_ns(now_ns); }

 private:
  std::array<pipeline::ProgressWatch, 3> stages_;
  std::uint8_t stalled_ = 0;
};

// "acquisition (no frame for 2.1 s)" etc. for the stages in `bits`; the most upstream one is
// named first because the ones after it are waiting for it.
std::string describe_stall(std::uint8_t bits, const ProgressMonitor& m, std::int64_t now_ns);

}  // namespace sempose::service
