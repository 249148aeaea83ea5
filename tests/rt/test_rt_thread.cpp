#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <atomic>

#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"
#include "sempose/rt/memory_lock.hpp"
#include "sempose/rt/rt_thread.hpp"

namespace {

using sempose::rt::RtThread;
using sempose::rt::RtThreadConfig;

TEST(RtThread, RunsTheBodyPinnedWithTheRequestedPolicyOrSaysWhy) {
  RtThreadConfig cfg;
  cfg.name = "test-rt";
  cfg.cpu = 0;
  cfg.priority = 10;
  std::atomic<int> policy{-1}, cpu{-1};
  std::atomic<bool> armed{false};
  RtThread t;
  const auto status = t.start(cfg, [&] {
    sched_param p{};
    int pol = 0;
    pthread_getschedparam(pthread_self(), &pol, &p);
    policy = pol;
    cpu = sched_getcpu();
    armed = sempose::rt::alloc::this_thread_armed();
  });
  ASSERT_TRUE(status.ok) << status.message;
  t.join();
  EXPECT_EQ(cpu.load(), 0);
  EXPECT_TRUE(armed.load());  // allocation counting is on inside RT bodies
  if (t.warning().empty()) {
    EXPECT_EQ(policy.load(), SCHED_FIFO) << t.placement();
  } else {
    // Degraded (no privilege): the warning must say what is missing and how to grant it.
    EXPECT_NE(t.warning().find("SCHED_FIFO"), std::string::npos);
    EXPECT_NE(t.warning().find("CAP_SYS_NICE"), std::string::npos);
  }
}

// A stage configured `cpu: -1` (not pinned) may run on every core the process may use, also when
// the thread starting it is pinned (`sempose run` pins its main thread to pipeline.non_rt_cpu
// first): it used to inherit that one core and share it with the main thread, said "unpinned".
TEST(RtThread, AnUnpinnedThreadDoesNotInheritItsCreatorsCore) {
  cpu_set_t process;
  ASSERT_EQ(sched_getaffinity(0, sizeof process, &process), 0);
  if (CPU_COUNT(&process) < 2) GTEST_SKIP() << "needs two cores";
  int first = 0;
  while (!CPU_ISSET(first, &process)) ++first;
  cpu_set_t one;
  CPU_ZERO(&one);
  CPU_SET(first, &one);
  ASSERT_EQ(pthread_setaffinity_np(pthread_self(), sizeof one, &one), 0);  // as run's main thread
  std::atomic<int> cores{-1};
  RtThread t;
  RtThreadConfig cfg;
  cfg.name = "test-unpinned";
  const auto status = t.start(cfg, [&] {
    cpu_set_t mine;
    if (pthread_getaffinity_np(pthread_self(), sizeof mine, &mine) == 0) cores = CPU_COUNT(&mine);
  });
  t.join();
  pthread_setaffinity_np(pthread_self(), sizeof process, &process);
  ASSERT_TRUE(status.ok) << status.message;
  EXPECT_EQ(cores.load(), CPU_COUNT(&process)) << t.placement();
  EXPECT_NE(t.placement().find("unpinned"), std::string::npos) << t.placement();
}

TEST(RtThread, RejectsAnImpossiblePriorityWithAMessage) {
  RtThreadConfig cfg;
  cfg.priority = 150;
  RtThread t;
  const auto status = t.start(cfg, [] {});
  EXPECT_FALSE(status.ok);
  EXPECT_NE(status.message.find("priority 150"), std::string::npos) << status.message;
}

TEST(RtThread, StrictModeRefusesANonexistentCpu) {
  RtThreadConfig cfg;
  cfg.cpu = 4096;
  cfg.strict = true;
  RtThread t;
  const auto status = t.start(cfg, [] {});
  EXPECT_FALSE(status.ok);
  EXPECT_NE(status.message.find("cpu 4096"), std::string::npos) << status.message;

  cfg.strict = false;  // development: warn and run unpinned
  std::atomic<bool> ran{false};
  RtThread t2;
  ASSERT_TRUE(t2.start(cfg, [&] { ran = true; }).ok);
  t2.join();
  EXPECT_TRUE(ran.load());
  EXPECT_NE(t2.warning().find("cpu 4096"), std::string::npos);
}

TEST(MemoryLock, CpuDmaLatencyHoldReportsAMissingDevice) {
  sempose::rt::CpuDmaLatencyHold hold;
  const auto strict = hold.acquire(true, "/nonexistent/cpu_dma_latency");
  EXPECT_FALSE(strict.ok);
  EXPECT_NE(strict.message.find("/nonexistent/cpu_dma_latency"), std::string::npos);
  const auto lax = hold.acquire(false, "/nonexistent/cpu_dma_latency");
  EXPECT_TRUE(lax.ok);
  EXPECT_FALSE(lax.message.empty());
  EXPECT_FALSE(hold.held());
}

TEST(Clock, SleepUntilReachesTheDeadline) {
  const std::int64_t deadline = sempose::rt::now_ns() + 2 * sempose::rt::kNsPerMs;
  sempose::rt::sleep_until_ns(deadline);
  EXPECT_GE(sempose::rt::now_ns(), deadline);
  const timespec ts = sempose::rt::to_timespec(1'234'567'890'123);
  EXPECT_EQ(ts.tv_sec, 1234);
  EXPECT_EQ(ts.tv_nsec, 567'890'123);
  EXPECT_EQ(sempose::rt::to_ns(ts), 1'234'567'890'123);
}

}  // namespace
