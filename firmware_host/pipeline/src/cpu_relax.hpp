// A spin-wait hint for the stages' busy loops (polling: spin, or a scan due any moment).
#pragma once

namespace sempose::pipeline {

inline void cpu_relax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield" ::: "memory");
#else
  asm volatile("" ::: "memory");
#endif
}

}  // namespace sempose::pipeline
