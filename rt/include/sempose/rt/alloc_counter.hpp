// Counts heap calls made by threads marked real-time. Part of the product, not only of the
// tests: `sempose run` reports `rt_allocs`, so a deployment is validated on the real box.
//
// How: in normal builds the malloc family (malloc, calloc, realloc, free, the aligned forms)
// is replaced by thin wrappers around glibc's __libc_* entry points; operator new/delete in
// libstdc++ call malloc/free, so they are counted too. In sanitizer builds the sanitizer owns
// malloc; the sanitizer allocator's malloc/free hooks count every heap call instead.
// The check on a thread-local flag costs a few instructions per call.
#pragma once

#include <cstdint>

namespace sempose::rt::alloc {

// Start/stop counting heap calls made by the calling thread.
void arm_this_thread() noexcept;
void disarm_this_thread() noexcept;
bool this_thread_armed() noexcept;

// Allocations (malloc, calloc, realloc, aligned forms, operator new) by armed threads.
std::uint64_t allocations() noexcept;
// Frees (free, operator delete) of non-null pointers by armed threads.
std::uint64_t frees() noexcept;
// Allocations made by the calling thread while armed.
std::uint64_t this_thread_allocations() noexcept;

// True when raw malloc calls are counted (every build since the sanitizer hooks).
bool counts_malloc() noexcept;

// RAII: arm for a scope (tests).
class ScopedArm {
 public:
  ScopedArm() noexcept { arm_this_thread(); }
  ~ScopedArm() { disarm_this_thread(); }
  ScopedArm(const ScopedArm&) = delete;
  ScopedArm& operator=(const ScopedArm&) = delete;
};

}  // namespace sempose::rt::alloc
