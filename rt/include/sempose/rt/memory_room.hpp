// How much memory a setup may still take (not RT): the kernel's MemAvailable, and, under an
// address-space limit (RLIMIT_AS, `ulimit -v`), what the process has not mapped yet. The pattern
// bank and the replay of a recording check their sizes against it before allocating, so that a
// limit gives a named error at once instead of std::bad_alloc after a long load.
#pragma once

#include <algorithm>
#include <cstdint>

namespace sempose::rt {

struct MemoryRoom {
  std::uint64_t available = 0;     // MemAvailable, bytes (0: unknown)
  bool address_limited = false;    // RLIMIT_AS set
  std::uint64_t address_limit = 0; // RLIMIT_AS, bytes
  std::uint64_t address_left = 0;  // RLIMIT_AS minus what is mapped now, bytes
  // The least of what is known (0: nothing known, no limit to apply).
  std::uint64_t least() const noexcept {
    if (!address_limited) return available;
    return available == 0 ? address_left : std::min(available, address_left);
  }
};

MemoryRoom memory_room();

}  // namespace sempose::rt
