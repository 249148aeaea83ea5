// Pool of N preallocated frame slots (metadata + aligned pixel buffer), handed between
// pipeline stages by index through SpscRings. All memory is allocated once in the
// constructor (setup, non-RT); nothing is allocated, copied or freed while running.
//
// Ownership is explicit: every slot carries an atomic owner tag and a stage takes a slot
// only by `transfer(index, from, to)`, a compare-and-swap that fails if the slot is not
// held by `from`. A slot therefore has exactly one owner at a time, and a logic error
// (double hand-off, use after release) shows up as a failed transfer instead of a silent
// overwrite of a frame another stage is still reading.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <new>
#include <span>
#include <vector>

#include "sempose/rt/cache_line.hpp"

namespace sempose::rt {

// Who holds a slot. Stages are free to use any values >= kFirstStage for their own roles.
enum class SlotOwner : std::uint8_t { kFree = 0, kFirstStage = 1 };

template <typename Meta, typename Pixel>
class FramePool {
 public:
  using Index = std::uint16_t;

  struct Slot {
    Meta meta{};
    Pixel* pixels = nullptr;     // capacity_pixels, 64-byte aligned
    std::size_t capacity_pixels = 0;
    std::span<Pixel> buffer() noexcept { return {pixels, capacity_pixels}; }
    std::span<const Pixel> buffer() const noexcept { return {pixels, capacity_pixels}; }
  };

  // Setup only: allocates slot_count buffers of capacity_pixels each and touches every page.
  FramePool(std::size_t slot_count, std::size_t capacity_pixels)
      : slots_(slot_count), owners_(slot_count) {
    const std::size_t bytes = round_up(capacity_pixels * sizeof(Pixel), kCacheLine);
    for (auto& slot : slots_) {
      void* p = std::aligned_alloc(kCacheLine, bytes);
      if (p == nullptr) throw std::bad_alloc();
      slot.pixels = static_cast<Pixel*>(p);
      slot.capacity_pixels = capacity_pixels;
      for (std::size_t i = 0; i < capacity_pixels; ++i) slot.pixels[i] = Pixel{};  // prefault
    }
    for (auto& o : owners_) o.value.store(SlotOwner::kFree, std::memory_order_relaxed);
  }
  ~FramePool() {
    for (auto& slot : slots_) std::free(slot.pixels);
  }
  FramePool(const FramePool&) = delete;
  FramePool& operator=(const FramePool&) = delete;

  std::size_t size() const noexcept { return slots_.size(); }
  std::size_t capacity_pixels() const noexcept {
    return slots_.empty() ? 0 : slots_[0].capacity_pixels;
  }
  Slot& operator[](Index i) noexcept { return slots_[i]; }
  const Slot& operator[](Index i) const noexcept { return slots_[i]; }

  // Moves ownership of slot i from `from` to `to`; false if `from` did not hold it.
  // acq_rel: the new owner sees everything the old owner wrote into the slot.
  bool transfer(Index i, SlotOwner from, SlotOwner to) noexcept {
    if (i >= slots_.size()) return false;
    return owners_[i].value.compare_exchange_strong(from, to, std::memory_order_acq_rel,
                                                    std::memory_order_relaxed);
  }
  SlotOwner owner(Index i) const noexcept {
    return owners_[i].value.load(std::memory_order_acquire);
  }

 private:
  static constexpr std::size_t round_up(std::size_t n, std::size_t a) { return (n + a - 1) / a * a; }
  std::vector<Slot> slots_;
  std::vector<CacheAligned<std::atomic<SlotOwner>>> owners_;
};

constexpr SlotOwner stage_owner(std::uint8_t stage) noexcept {
  return static_cast<SlotOwner>(static_cast<std::uint8_t>(SlotOwner::kFirstStage) + stage);
}

}  // namespace sempose::rt
