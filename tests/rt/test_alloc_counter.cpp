#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "sempose/rt/alloc_counter.hpp"

namespace alloc = sempose::rt::alloc;

namespace {

// Opaque to the optimiser, so a new/delete pair cannot be elided.
void* volatile g_sink = nullptr;

TEST(AllocCounter, CatchesADeliberateOperatorNew) {
  const auto before = alloc::allocations();
  std::uint64_t mine = 0;
  {
    alloc::ScopedArm arm;
    auto* p = new int(7);
    g_sink = p;
    delete p;
    mine = alloc::this_thread_allocations();
  }
  EXPECT_EQ(mine, 1u);
  EXPECT_EQ(alloc::allocations() - before, 1u);
}

TEST(AllocCounter, CatchesAVectorGrowingAndAString) {
  alloc::ScopedArm arm;
  const auto before = alloc::this_thread_allocations();
  std::vector<int> v;
  for (int i = 0; i < 100; ++i) v.push_back(i);
  std::string s(200, 'x');
  g_sink = s.data();
  EXPECT_GE(alloc::this_thread_allocations() - before, 2u);
}

TEST(AllocCounter, CatchesRawMallocWhenTheBuildCountsIt) {
  if (!alloc::counts_malloc()) GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc";
  alloc::ScopedArm arm;
  const auto before = alloc::this_thread_allocations();
  void* p = std::malloc(64);
  g_sink = p;
  std::free(p);
  void* q = nullptr;
  EXPECT_EQ(posix_memalign(&q, 64, 256), 0);
  std::free(q);
  EXPECT_EQ(alloc::this_thread_allocations() - before, 2u);
}

TEST(AllocCounter, IgnoresThreadsThatAreNotArmed) {
  const auto before = alloc::allocations();
  std::thread other([] {
    auto v = std::make_unique<std::vector<int>>(1000);
    g_sink = v.get();
  });
  other.join();  // thread creation itself allocates on this (unarmed) thread: not counted
  EXPECT_EQ(alloc::allocations(), before);
}

TEST(AllocCounter, AllocationFreeCodeCountsZero) {
  alloc::ScopedArm arm;
  const auto before = alloc::this_thread_allocations();
  int buffer[256];
  for (int i = 0; i < 256; ++i) buffer[i] = i * i;
  g_sink = buffer;
  EXPECT_EQ(alloc::this_thread_allocations() - before, 0u);
}

}  // namespace
