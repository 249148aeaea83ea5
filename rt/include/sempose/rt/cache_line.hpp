// Cache-line size and a padded wrapper so hot atomics never share a line (false sharing).
#pragma once

#include <cstddef>

namespace sempose::rt {

// 64 B on every x86-64 and most ARMv8 cores; std::hardware_destructive_interference_size
// is not usable in headers shared across compilers (GCC warns it may change).
inline constexpr std::size_t kCacheLine = 64;

template <typename T>
struct alignas(kCacheLine) CacheAligned {
  T value;
};
static_assert(sizeof(CacheAligned<char>) == kCacheLine);

}  // namespace sempose::rt
