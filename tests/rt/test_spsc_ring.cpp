#include <gtest/gtest.h>

#include <cstdint>
#include <thread>

#include "sempose/rt/spsc_ring.hpp"

namespace {

using sempose::rt::SpscRing;

TEST(SpscRing, FillsToCapacityAndRefusesMore) {
  SpscRing<int, 8> ring;
  for (int i = 0; i < 8; ++i) EXPECT_TRUE(ring.try_push(i));
  EXPECT_FALSE(ring.try_push(99));
  EXPECT_EQ(ring.size(), 8u);
  int v = -1;
  for (int i = 0; i < 8; ++i) {
    ASSERT_TRUE(ring.try_pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(ring.try_pop(v));
  EXPECT_TRUE(ring.empty());
}

TEST(SpscRing, WrapsAroundManyTimes) {
  SpscRing<std::uint32_t, 4> ring;
  std::uint32_t out = 0;
  for (std::uint32_t i = 0; i < 1000; ++i) {
    ASSERT_TRUE(ring.try_push(i));
    ASSERT_TRUE(ring.try_pop(out));
    ASSERT_EQ(out, i);
  }
}

TEST(SpscRing, HotIndicesDoNotShareACacheLine) {
  // head/tail layout is what makes the ring fast; a refactor that packs them fails here.
  static_assert(alignof(SpscRing<int, 8>) >= sempose::rt::kCacheLine);
  EXPECT_GE(sizeof(SpscRing<int, 8>), 4 * sempose::rt::kCacheLine);
}

struct Item {
  std::uint64_t seq;
  std::uint64_t check;  // derived from seq: a torn or stale copy fails the check
};

TEST(SpscRing, TwoThreadStressKeepsOrderAndContent) {
  constexpr std::uint64_t kItems = 10'000'000;
  static SpscRing<Item, 1024> ring;
  std::thread producer([] {
    for (std::uint64_t i = 0; i < kItems;) {
      if (ring.try_push(Item{i, i * 0x9E3779B97F4A7C15ULL})) ++i;
    }
  });
  std::uint64_t expected = 0;
  std::uint64_t bad = 0;
  Item item{};
  while (expected < kItems) {
    if (ring.try_pop(item)) {
      if (item.seq != expected || item.check != expected * 0x9E3779B97F4A7C15ULL) ++bad;
      ++expected;
    }
  }
  producer.join();
  EXPECT_EQ(bad, 0u);
  EXPECT_TRUE(ring.empty());
}

}  // namespace
