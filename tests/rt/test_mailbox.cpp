#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "sempose/rt/mailbox.hpp"

namespace {

using sempose::rt::Mailbox;

// 5 words: larger than any single atomic store, so tearing would be visible.
struct Wide {
  std::uint64_t a, b, c, d, e;
};

TEST(Mailbox, ReturnsLastPublishedValue) {
  Mailbox<Wide> box;
  EXPECT_EQ(box.read().a, 0u);
  box.publish({1, 2, 3, 4, 5});
  box.publish({6, 7, 8, 9, 10});
  const Wide w = box.read();
  EXPECT_EQ(w.a, 6u);
  EXPECT_EQ(w.e, 10u);
  EXPECT_EQ(box.version(), 3u);  // the constructor publishes the initial value
}

TEST(Mailbox, ReadersNeverSeeATornValue) {
  static Mailbox<Wide> box;
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> torn{0};
  std::atomic<std::uint64_t> reads{0};
  std::thread reader([&] {
    std::uint64_t last = 0;
    while (!stop.load(std::memory_order_relaxed)) {
      const Wide w = box.read();
      reads++;
      if (w.a == 0) continue;  // the initial value, before the first publish
      if (w.b != w.a + 1 || w.c != w.a + 2 || w.d != w.a + 3 || w.e != w.a * 3) torn++;
      if (w.a < last) torn++;  // values only move forward
      last = w.a;
    }
  });
  for (std::uint64_t i = 1; i <= 2'000'000; ++i) box.publish({i, i + 1, i + 2, i + 3, i * 3});
  while (reads.load() < 1000) std::this_thread::yield();
  stop = true;
  reader.join();
  EXPECT_EQ(torn.load(), 0u);
  EXPECT_GT(reads.load(), 0u);
}

}  // namespace
