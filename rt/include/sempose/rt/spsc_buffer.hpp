// Single-producer single-consumer ring whose capacity is chosen at setup (storage allocated
// once, by allocate()), for output a non-RT writer drains in batches: the CSV pose sink's
// records and the candump log's bytes. Same discipline as SpscRing (rigtorp form: indices on
// their own cache lines, each side caching the other's, acquire/release only); the producer
// pushes all of a batch or nothing, the consumer reads the oldest pending items that lie
// contiguously in storage and then consumes what it used. push/readable/consume are RT-safe.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <memory>
#include <span>
#include <type_traits>

#include "sempose/rt/cache_line.hpp"

namespace sempose::rt {

template <typename T>
class SpscBuffer {
  static_assert(std::is_nothrow_copy_assignable_v<T>, "items are copied on the RT path");

 public:
  SpscBuffer() = default;
  SpscBuffer(const SpscBuffer&) = delete;
  SpscBuffer& operator=(const SpscBuffer&) = delete;

  // Setup: room for at least min_capacity items (rounded up to a power of two, at least 2).
  // Not concurrent with push or read.
  void allocate(std::size_t min_capacity) {
    std::size_t capacity = 2;
    while (capacity < min_capacity) capacity <<= 1;
    slots_ = std::make_unique<T[]>(capacity);
    capacity_ = capacity;
    head_.value.store(0, std::memory_order_relaxed);
    tail_.value.store(0, std::memory_order_relaxed);
    head_cache_ = tail_cache_ = 0;
  }
  std::size_t capacity() const noexcept { return capacity_; }
  // Items pushed and not yet consumed (exact when neither side is running, e.g. at exit).
  std::size_t pending() const noexcept {
    return tail_.value.load(std::memory_order_acquire) - head_.value.load(std::memory_order_acquire);
  }

  // Producer: all n items, or nothing (false) when they do not fit. Never blocks.
  bool try_push(const T* items, std::size_t n) noexcept {
    const std::size_t tail = tail_.value.load(std::memory_order_relaxed);
    if (capacity_ - (tail - head_cache_) < n) {
      head_cache_ = head_.value.load(std::memory_order_acquire);
      if (capacity_ - (tail - head_cache_) < n) return false;
    }
    const std::size_t mask = capacity_ - 1;
    for (std::size_t i = 0; i < n; ++i) slots_[(tail + i) & mask] = items[i];
    tail_.value.store(tail + n, std::memory_order_release);
    return true;
  }
  bool try_push(const T& item) noexcept { return try_push(&item, 1); }

  // Consumer: the oldest pending items that lie contiguously in storage (empty when none;
  // after a wrap-around the rest comes with the next call).
  std::span<const T> readable() noexcept {
    const std::size_t head = head_.value.load(std::memory_order_relaxed);
    tail_cache_ = tail_.value.load(std::memory_order_acquire);
    const std::size_t start = head & (capacity_ - 1);
    return {slots_.get() + start, std::min(tail_cache_ - head, capacity_ - start)};
  }
  // Consumer: n of the readable items are done with; their room goes back to the producer.
  void consume(std::size_t n) noexcept {
    head_.value.store(head_.value.load(std::memory_order_relaxed) + n, std::memory_order_release);
  }

 private:
  std::unique_ptr<T[]> slots_;
  std::size_t capacity_ = 0;
  CacheAligned<std::atomic<std::size_t>> head_{};  // consumer-owned
  alignas(kCacheLine) std::size_t tail_cache_ = 0;
  CacheAligned<std::atomic<std::size_t>> tail_{};  // producer-owned
  alignas(kCacheLine) std::size_t head_cache_ = 0;
};

}  // namespace sempose::rt
