// Process-wide RT memory setup (README: Real-time rules) and the /dev/cpu_dma_latency hold.
#pragma once

#include <cstddef>

#include "sempose/rt/result.hpp"

namespace sempose::rt {

// mallopt(M_MMAP_MAX, 0) and M_TRIM_THRESHOLD=-1 (heap memory is never returned to the
// kernel, so a later malloc cannot fault), then mlockall(MCL_CURRENT|MCL_FUTURE).
// Without the privilege: ok with a warning message, unless strict.
Status lock_process_memory(bool strict);

// Holds /dev/cpu_dma_latency at 0 µs while alive (as cyclictest does), keeping CPUs out of
// deep C-states. Without access: a warning, unless strict.
class CpuDmaLatencyHold {
 public:
  CpuDmaLatencyHold() = default;
  ~CpuDmaLatencyHold();
  CpuDmaLatencyHold(const CpuDmaLatencyHold&) = delete;
  CpuDmaLatencyHold& operator=(const CpuDmaLatencyHold&) = delete;
  Status acquire(bool strict, const char* path = "/dev/cpu_dma_latency");
  bool held() const noexcept { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

// Writes every page of [p, p+bytes) so it is resident before the loop starts.
void prefault(void* p, std::size_t bytes) noexcept;

}  // namespace sempose::rt
