// Latest-value mailbox: one writer publishes, any number of readers read the newest value.
// A seqlock by the portable recipe (Boehm, "Can seqlocks get along with programming language
// memory models?"): the payload is stored as relaxed atomic words and ordered by fences, so
// there is no data race in the C++ model and no reliance on x86's strong ordering.
// Neither side ever blocks: a reader that races a write retries (bounded by the writer rate).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "sempose/rt/cache_line.hpp"

namespace sempose::rt {

namespace detail {
// ThreadSanitizer does not model atomic_thread_fence (GCC even drops it with -Wtsan), so
// under TSan the payload words carry the ordering themselves (release stores / acquire
// loads). Same guarantees, checked by TSan; normal builds keep the fence recipe.
#if defined(__SANITIZE_THREAD__)
inline constexpr std::memory_order kPayloadStore = std::memory_order_release;
inline constexpr std::memory_order kPayloadLoad = std::memory_order_acquire;
#else
inline constexpr std::memory_order kPayloadStore = std::memory_order_relaxed;
inline constexpr std::memory_order kPayloadLoad = std::memory_order_relaxed;
#endif
}  // namespace detail

template <typename T>
class Mailbox {
  static_assert(std::is_trivially_copyable_v<T>, "the payload is copied as raw words");

 public:
  Mailbox() noexcept { publish(T{}); }
  explicit Mailbox(const T& initial) noexcept { publish(initial); }
  Mailbox(const Mailbox&) = delete;
  Mailbox& operator=(const Mailbox&) = delete;

  // Single writer.
  void publish(const T& value) noexcept {
    std::array<std::uint64_t, kWords> words{};
    std::memcpy(words.data(), &value, sizeof(T));
    const std::uint32_t seq = seq_.load(std::memory_order_relaxed);
    seq_.store(seq + 1, std::memory_order_relaxed);  // odd: write in progress
    std::atomic_thread_fence(std::memory_order_release);
    for (std::size_t i = 0; i < kWords; ++i) data_[i].store(words[i], detail::kPayloadStore);
    seq_.store(seq + 2, std::memory_order_release);  // even: stable
  }

  // Any reader. Returns the newest complete value; never a torn one.
  T read() const noexcept {
    std::array<std::uint64_t, kWords> words{};
    std::uint32_t before = 0;
    std::uint32_t after = 0;
    do {
      before = seq_.load(std::memory_order_acquire);
      for (std::size_t i = 0; i < kWords; ++i) words[i] = data_[i].load(detail::kPayloadLoad);
      std::atomic_thread_fence(std::memory_order_acquire);
      after = seq_.load(std::memory_order_relaxed);
    } while ((before & 1U) != 0 || before != after);
    T value;
    std::memcpy(&value, words.data(), sizeof(T));
    return value;
  }

  // Number of publishes so far; lets a reader see whether anything new arrived.
  std::uint32_t version() const noexcept { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;
  alignas(kCacheLine) std::atomic<std::uint32_t> seq_{0};
  std::array<std::atomic<std::uint64_t>, kWords> data_{};
};

}  // namespace sempose::rt
