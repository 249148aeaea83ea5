#include <gtest/gtest.h>

#include <cstdint>
#include <thread>

#include "sempose/rt/frame_pool.hpp"
#include "sempose/rt/spsc_ring.hpp"

namespace {

using sempose::rt::FramePool;
using sempose::rt::SlotOwner;
using sempose::rt::stage_owner;

struct Meta {
  std::uint64_t seq = 0;
};

TEST(FramePool, SlotsAreAlignedAndSized) {
  FramePool<Meta, std::uint16_t> pool(4, 192 * 192);
  ASSERT_EQ(pool.size(), 4u);
  for (std::uint16_t i = 0; i < 4; ++i) {
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(pool[i].pixels) % 64, 0u);
    EXPECT_EQ(pool[i].buffer().size(), 192u * 192u);
    EXPECT_EQ(pool.owner(i), SlotOwner::kFree);
  }
  EXPECT_NE(pool[0].pixels, pool[1].pixels);
}

TEST(FramePool, TransferRefusesASlotTheCallerDoesNotHold) {
  FramePool<Meta, std::uint16_t> pool(2, 16);
  const auto a = stage_owner(0), b = stage_owner(1);
  EXPECT_TRUE(pool.transfer(0, SlotOwner::kFree, a));
  EXPECT_FALSE(pool.transfer(0, SlotOwner::kFree, b));  // already taken: never owned twice
  EXPECT_FALSE(pool.transfer(0, b, SlotOwner::kFree));  // b never held it
  EXPECT_TRUE(pool.transfer(0, a, b));
  EXPECT_EQ(pool.owner(0), b);
  EXPECT_FALSE(pool.transfer(7, SlotOwner::kFree, a));  // out of range
}

// Two stages hand slots around through rings, as the pipeline does; every hand-off must
// succeed (one owner at a time) and the consumer must see what the producer wrote.
TEST(FramePool, SlotsHandedThroughRingsAreNeverOwnedTwice) {
  constexpr int kSlots = 8;
  constexpr std::uint64_t kFrames = 200'000;
  static FramePool<Meta, std::uint16_t> pool(kSlots, 64);
  static sempose::rt::SpscRing<std::uint16_t, 16> ready, returned;
  const auto producer_role = stage_owner(0), consumer_role = stage_owner(1);
  for (std::uint16_t i = 0; i < kSlots; ++i) {
    ASSERT_TRUE(pool.transfer(i, SlotOwner::kFree, producer_role));
    ASSERT_TRUE(returned.try_push(i));
  }
  std::uint64_t producer_faults = 0;
  std::thread producer([&] {
    for (std::uint64_t n = 0; n < kFrames;) {
      std::uint16_t i = 0;
      if (!returned.try_pop(i)) continue;
      if (pool.owner(i) != producer_role) ++producer_faults;
      pool[i].meta.seq = n;
      pool[i].pixels[0] = static_cast<std::uint16_t>(n);
      if (!pool.transfer(i, producer_role, consumer_role)) ++producer_faults;
      while (!ready.try_push(i)) {
      }
      ++n;
    }
  });
  std::uint64_t consumer_faults = 0;
  for (std::uint64_t n = 0; n < kFrames;) {
    std::uint16_t i = 0;
    if (!ready.try_pop(i)) continue;
    if (pool[i].meta.seq != n || pool[i].pixels[0] != static_cast<std::uint16_t>(n)) ++consumer_faults;
    if (!pool.transfer(i, consumer_role, producer_role)) ++consumer_faults;
    while (!returned.try_push(i)) {
    }
    ++n;
  }
  producer.join();
  EXPECT_EQ(producer_faults, 0u);
  EXPECT_EQ(consumer_faults, 0u);
}

}  // namespace
