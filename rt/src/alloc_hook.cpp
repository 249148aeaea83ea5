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
// Normal builds replace the malloc family, sanitizer builds hook the sanitizer's allocator:
// raw malloc is counted in both.
bool counts_malloc() noexcept { return true; }
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
// Sanitizer builds: the sanitizer owns malloc, so the family cannot be replaced. Its allocator
// calls hooks on every allocation and free instead — malloc, calloc, realloc, the aligned forms
// and operator new alike — so FFTW's own fftwf_malloc and any raw malloc are counted here too
// (counting only operator new let a plan that mallocs inside fftwf_execute pass as clean).
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*, std::size_t),
                                                         void (*free_hook)(const volatile void*));
namespace {
void on_sanitizer_malloc(const volatile void*, std::size_t) { count_alloc(); }
void on_sanitizer_free(const volatile void* p) { count_free(const_cast<const void*>(p)); }
// Installed before main(); static initialisation of this object runs before any armed thread.
const int g_hooks_installed = __sanitizer_install_malloc_and_free_hooks(on_sanitizer_malloc, on_sanitizer_free);
}  // namespace
#endif
