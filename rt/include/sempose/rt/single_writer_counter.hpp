// A counter with exactly one writing thread, read by others (status lines, summaries). The
// writer adds with a relaxed load + store instead of fetch_add: no locked read-modify-write
// on the RT path, and correct because no other thread ever writes it. Readers see some
// recent value (relaxed).
#pragma once

#include <atomic>
#include <cstdint>

namespace sempose::rt {

inline void add_single_writer(std::atomic<std::uint64_t>& counter, std::uint64_t n = 1) noexcept {
  counter.store(counter.load(std::memory_order_relaxed) + n, std::memory_order_relaxed);
}

}  // namespace sempose::rt
