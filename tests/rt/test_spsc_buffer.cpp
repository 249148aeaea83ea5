// The setup-sized SPSC buffer (CSV pose sink, candump log): all-or-nothing batches,
// contiguous reads across the wrap-around, and order and content under two threads.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "sempose/rt/spsc_buffer.hpp"

using sempose::rt::SpscBuffer;

TEST(SpscBuffer, BatchesFitWhollyOrNotAtAll) {
  SpscBuffer<char> b;
  b.allocate(5);
  EXPECT_EQ(b.capacity(), 8u);
  EXPECT_TRUE(b.readable().empty());
  EXPECT_TRUE(b.try_push("abcde", 5));
  EXPECT_FALSE(b.try_push("wxyz", 4));  // 3 free: nothing is written
  EXPECT_TRUE(b.try_push("xyz", 3));
  auto r = b.readable();
  ASSERT_EQ(r.size(), 8u);
  EXPECT_EQ(std::string(r.begin(), r.end()), "abcdexyz");
  b.consume(6);
  EXPECT_TRUE(b.try_push("1234", 4));  // wraps around
  r = b.readable();
  EXPECT_EQ(std::string(r.begin(), r.end()), "yz");  // up to the end of storage
  b.consume(r.size());
  r = b.readable();
  EXPECT_EQ(std::string(r.begin(), r.end()), "1234");
  b.consume(r.size());
  EXPECT_TRUE(b.readable().empty());
}

TEST(SpscBuffer, TwoThreadStressKeepsOrderAndContent) {
  SpscBuffer<std::uint32_t> b;
  b.allocate(64);
  constexpr std::uint32_t kItems = 2'000'000;
  std::thread producer([&] {
    std::uint32_t next = 0;
    while (next < kItems) {
      const std::uint32_t batch[3] = {next, next + 1, next + 2};
      const std::size_t n = std::min<std::uint32_t>(3, kItems - next);
      if (b.try_push(batch, n)) next += static_cast<std::uint32_t>(n);
    }
  });
  std::uint32_t expect = 0;
  bool in_order = true;
  while (expect < kItems) {
    const auto r = b.readable();
    for (std::uint32_t v : r) {
      if (v != expect) in_order = false;
      ++expect;
    }
    b.consume(r.size());
  }
  producer.join();
  EXPECT_TRUE(in_order);
  EXPECT_EQ(expect, kItems);
}
