// Single-producer single-consumer ring of fixed capacity (rigtorp/SPSCQueue form).
// Storage is inline (no allocation ever); head and tail live on their own cache lines and
// each side keeps a cached copy of the other's index, so the common case touches no shared
// line. Only acquire/release ordering is used, so it is correct on weakly ordered CPUs too.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <optional>
#include <type_traits>

#include "sempose/rt/cache_line.hpp"

namespace sempose::rt {

template <typename T, std::size_t Capacity>
class SpscRing {
  static_assert(Capacity >= 2, "a ring needs room for at least two items");
  static_assert((Capacity & (Capacity - 1)) == 0, "capacity must be a power of two");
  static_assert(std::is_nothrow_copy_assignable_v<T>, "items are copied on the RT path");

 public:
  static constexpr std::size_t kCapacity = Capacity;

  SpscRing() noexcept = default;
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  // Producer side. Returns false (and stores nothing) when full; never blocks.
  bool try_push(const T& item) noexcept {
    const std::size_t tail = tail_.value.load(std::memory_order_relaxed);
    if (tail - head_cache_ == Capacity) {
      head_cache_ = head_.value.load(std::memory_order_acquire);
      if (tail - head_cache_ == Capacity) return false;
    }
    slots_[tail & kMask] = item;
    tail_.value.store(tail + 1, std::memory_order_release);
    return true;
  }

  // Consumer side. Returns false when empty; never blocks.
  bool try_pop(T& out) noexcept {
    const std::size_t head = head_.value.load(std::memory_order_relaxed);
    if (head == tail_cache_) {
      tail_cache_ = tail_.value.load(std::memory_order_acquire);
      if (head == tail_cache_) return false;
    }
    out = slots_[head & kMask];
    head_.value.store(head + 1, std::memory_order_release);
    return true;
  }

  std::optional<T> try_pop() noexcept {
    T out;
    if (!try_pop(out)) return std::nullopt;
    return out;
  }

  // Approximate when called concurrently; exact when both sides are quiet.
  std::size_t size() const noexcept {
    const std::size_t tail = tail_.value.load(std::memory_order_acquire);
    const std::size_t head = head_.value.load(std::memory_order_acquire);
    return tail - head;
  }
  bool empty() const noexcept { return size() == 0; }

 private:
  static constexpr std::size_t kMask = Capacity - 1;

  // Consumer-owned line: head plus the consumer's cached tail.
  CacheAligned<std::atomic<std::size_t>> head_{};
  alignas(kCacheLine) std::size_t tail_cache_ = 0;
  // Producer-owned line: tail plus the producer's cached head.
  CacheAligned<std::atomic<std::size_t>> tail_{};
  alignas(kCacheLine) std::size_t head_cache_ = 0;
  alignas(kCacheLine) std::array<T, Capacity> slots_{};
};

}  // namespace sempose::rt
