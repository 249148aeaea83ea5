// Real-time thread: name, CPU affinity, SCHED_FIFO priority (explicit-sched attributes, or
// the policy is silently inherited), a prefaulted stack, and heap-call counting armed before
// the body runs. Without the privilege it warns and runs at normal priority, unless strict.
#pragma once

#include <pthread.h>

#include <cstddef>
#include <functional>
#include <string>

#include "sempose/rt/result.hpp"

namespace sempose::rt {

struct RtThreadConfig {
  std::string name = "sempose-rt";        // at most 15 characters are kept (kernel limit)
  int cpu = -1;                           // -1: no pinning
  int priority = 0;                       // SCHED_FIFO 1..99; 0: SCHED_OTHER
  std::size_t stack_bytes = 1u << 20;     // reserved and locked
  std::size_t prefault_stack_bytes = 256u << 10;
  bool strict = false;                    // refuse to start instead of degrading
  bool count_allocations = true;          // arm rt::alloc counting before the body
};

class RtThread {
 public:
  RtThread() = default;
  ~RtThread();
  RtThread(const RtThread&) = delete;
  RtThread& operator=(const RtThread&) = delete;

  // Setup (may allocate). Returns failure with a message when the thread could not start
  // (or, in strict mode, could not get its policy/affinity). When it started degraded,
  // ok is true and warning() says what is missing and how to grant it.
  Status start(const RtThreadConfig& config, std::function<void()> body);
  void join();
  bool joinable() const noexcept { return started_; }
  const std::string& warning() const noexcept { return warning_; }
  // What the thread actually got, e.g. "SCHED_FIFO 80 on CPU 1".
  const std::string& placement() const noexcept { return placement_; }

 private:
  pthread_t handle_{};
  bool started_ = false;
  std::string warning_;
  std::string placement_;
  RtThreadConfig config_;
  std::function<void()> body_;
  static void* trampoline(void* self);
};

// Touches `bytes` of the calling thread's stack so later use causes no page faults.
void prefault_stack(std::size_t bytes) noexcept;

}  // namespace sempose::rt
