// See alloc_counter.hpp for why and how heap calls are counted.
#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

#include "sempose/rt/alloc_counter.hpp"

namespace {
// initial-exec TLS: reading it never allocates (a dynamic TLS block could call malloc).
thread_local bool t_armed __attribute__((tls_model("initial-exec"))) = false;
thread_local std::uint64_t t_allocs __attribute__((tls_model("initial-exec"))) = 0;
std::atomic<std::uint64_t> g_allocs{0};
std::atomic<std::uint64_t> g_frees{0};

inline void count_alloc() noexcept {
  if (t_armed) {
    ++t_allocs;
    g_allocs.fetch_add(1, std::memory_order_relaxed);
  }
}
inline void count_free(const void* p) noexcept {
  if (t_armed && p != nullptr) g_frees.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

namespace sempose::rt::alloc {
void arm_this_thread() noexcept { t_armed = true; }
void disarm_this_thread() noexcept { t_armed = false; }
bool this_thread_armed() noexcept { return t_armed; }
std::uint64_t allocations() noexcept { return g_allocs.load(std::memory_order_relaxed); }
std::uint64_t frees() noexcept { return g_frees.load(std::memory_order_relaxed); }
std::uint64_t this_thread_allocations() noexcept { return t_allocs; }
#ifdef SEMPOSE_SANITIZED
bool counts_malloc() noexcept { return false; }
#else
bool counts_malloc() noexcept { return true; }
#endif
}  // namespace sempose::rt::alloc

#ifndef SEMPOSE_SANITIZED
// glibc's documented way to replace malloc ("Replacing malloc" in the glibc manual):
// define the whole family; forward to the __libc_* entry points of glibc's own allocator.
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void __libc_free(void*);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);

void* malloc(std::size_t n) {
  count_alloc();
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) {
  count_alloc();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) {
  count_alloc();
  return __libc_realloc(p, n);
}
void free(void* p) {
  count_free(p);
  __libc_free(p);
}
void* memalign(std::size_t align, std::size_t n) {
  count_alloc();
  return __libc_memalign(align, n);
}
void* aligned_alloc(std::size_t align, std::size_t n) {
  count_alloc();
  return __libc_memalign(align, n);
}
int posix_memalign(void** out, std::size_t align, std::size_t n) {
  if (align % sizeof(void*) != 0 || (align & (align - 1)) != 0) return EINVAL;
  count_alloc();
  void* p = __libc_memalign(align, n);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t n) {
  count_alloc();
  return __libc_valloc(n);
}
void* pvalloc(std::size_t n) {
  count_alloc();
  return __libc_pvalloc(n);
}
}  // extern "C"
#else
// Sanitizer builds: count at operator new/delete, which then use the sanitizer's malloc.
namespace {
void* counted_new(std::size_t n) {
  count_alloc();
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* counted_new_aligned(std::size_t n, std::align_val_t a) {
  count_alloc();
  const auto align = static_cast<std::size_t>(a);
  if (void* p = std::aligned_alloc(align, (n + align - 1) / align * align)) return p;
  throw std::bad_alloc();
}
void counted_delete(void* p) noexcept {
  count_free(p);
  std::free(p);
}
}  // namespace
void* operator new(std::size_t n) { return counted_new(n); }
void* operator new[](std::size_t n) { return counted_new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try { return counted_new(n); } catch (...) { return nullptr; }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try { return counted_new(n); } catch (...) { return nullptr; }
}
void* operator new(std::size_t n, std::align_val_t a) { return counted_new_aligned(n, a); }
void* operator new[](std::size_t n, std::align_val_t a) { return counted_new_aligned(n, a); }
void operator delete(void* p) noexcept { counted_delete(p); }
void operator delete[](void* p) noexcept { counted_delete(p); }
void operator delete(void* p, std::size_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::size_t) noexcept { counted_delete(p); }
void operator delete(void* p, std::align_val_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::align_val_t) noexcept { counted_delete(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { counted_delete(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { counted_delete(p); }
#endif
