// SEMPOSE_CLONES: the hot loops are cloned for AVX-512 / AVX2 / baseline x86-64 and picked at
// load time (an ifunc). Under ThreadSanitizer the clones are left out: its instrumented ifunc
// resolver runs before the TSan runtime is initialised and crashes the binary before main.
#pragma once

#if defined(__SANITIZE_THREAD__)
#define SEMPOSE_CLONES
#else
#define SEMPOSE_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#endif
