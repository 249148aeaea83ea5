// GPIO code against a real gpio-sim chip (kernel module gpio-sim, configured through configfs):
//   SEMPOSE_GPIO_CHIP=gpiochip0 [SEMPOSE_GPIO_LINES=3,4,5] ./can_gpio_hw_test
// Lines: frame-sync input, pose-valid output, heartbeat output. Inputs are driven and outputs
// read back through /sys/devices/platform/<dev>/<chip>/sim_gpioN/{pull,value}. Without a
// chip every test skips, saying why.
#include <glob.h>
#include <poll.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "scripted_source.hpp"
#include "sempose/hal/gpio_frame_sync.hpp"
#include "sempose/hal/gpio_outputs.hpp"
#include "sempose/hal/gpio_synced_source.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"

namespace hal = sempose::hal;

namespace {

class GpioSimTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* chip = std::getenv("SEMPOSE_GPIO_CHIP");
    if (chip == nullptr || *chip == '\0')
      GTEST_SKIP() << "no gpio-sim chip: set SEMPOSE_GPIO_CHIP=<chip name> (this kernel has no gpio-sim; the "
                      "system test runs this binary inside a PREEMPT_RT VM with one)";
    chip_ = chip;
    glob_t g{};
    const std::string pattern = "/sys/devices/platform/*/" + chip_ + "/sim_gpio0";
    if (::glob(pattern.c_str(), 0, nullptr, &g) == 0 && g.gl_pathc > 0) {
      sim_dir_ = g.gl_pathv[0];
      sim_dir_.resize(sim_dir_.size() - std::string("/sim_gpio0").size());
    }
    ::globfree(&g);
    ASSERT_FALSE(sim_dir_.empty()) << "SEMPOSE_GPIO_CHIP=" << chip_ << " is not a gpio-sim chip (" << pattern << ")";
    if (const char* lines = std::getenv("SEMPOSE_GPIO_LINES")) {
      ASSERT_EQ(std::sscanf(lines, "%d,%d,%d", &in_, &valid_, &heartbeat_), 3) << "SEMPOSE_GPIO_LINES=in,valid,hb";
    }
  }
  void pull(int line, bool up) {
    std::ofstream f(sim_dir_ + "/sim_gpio" + std::to_string(line) + "/pull");
    f << (up ? "pull-up" : "pull-down");
    ASSERT_TRUE(f.good());
  }
  int value(int line) {
    std::ifstream f(sim_dir_ + "/sim_gpio" + std::to_string(line) + "/value");
    int v = -1;
    f >> v;
    return v;
  }
  std::string chip_, sim_dir_;
  int in_ = 3, valid_ = 4, heartbeat_ = 5;
};

}  // namespace

TEST_F(GpioSimTest, RisingEdgesArriveWithMonotonicTimestamps) {
  pull(in_, false);
  sempose::rt::Status st;
  auto sync = hal::GpioFrameSync::open({chip_, in_, false, "sempose-test"}, st);
  ASSERT_TRUE(sync) << st.message;
  std::int64_t ts[16];
  EXPECT_EQ(sync->read_edges(ts, 16), 0) << "nothing pending, and read_edges must not block";
  for (int i = 0; i < 5; ++i) {
    const std::int64_t before = sempose::rt::now_ns();
    pull(in_, true);
    ASSERT_TRUE(sync->wait(1'000'000'000)) << "edge " << i << " not seen";
    int n = 0;
    {
      sempose::rt::alloc::ScopedArm arm;
      n = sync->read_edges(ts, 16);
      EXPECT_EQ(sempose::rt::alloc::this_thread_allocations(), 0u);
    }
    ASSERT_EQ(n, 1);
    EXPECT_GE(ts[0], before);
    EXPECT_LE(ts[0], sempose::rt::now_ns());
    pull(in_, false);  // falling edge: not reported
  }
  ::usleep(10000);
  EXPECT_EQ(sync->read_edges(ts, 16), 0);
}

TEST_F(GpioSimTest, SyncedSourceCompletesOnTheRealEdge) {
  pull(in_, false);
  sempose::rt::Status st;
  auto sync = hal::GpioFrameSync::open({chip_, in_, false, "sempose-test"}, st);
  ASSERT_TRUE(sync) << st.message;
  sempose::test::ScriptedSource inner;
  inner.set_now(sempose::rt::now_ns());
  hal::GpioSyncedSource src(inner, *sync, 1'000'000'000);
  hal::FramePool pool(1, 16);
  ASSERT_EQ(src.start({}, pool[0]), hal::StartResult::kStarted);
  inner.finish();
  EXPECT_EQ(src.poll(), hal::PollResult::kBusy);
  pull(in_, true);
  pollfd p{src.wait_fd(), POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 1000), 1) << "wait_fd() never became readable";
  EXPECT_EQ(src.poll(), hal::PollResult::kDone);
  EXPECT_EQ(pool[0].meta.status, hal::FrameStatus::kOk);
  EXPECT_EQ(src.counters().edges.load(), 1u);
  pull(in_, false);
}

TEST_F(GpioSimTest, OutputsDriveTheLines) {
  for (bool active_low : {false, true}) {
    sempose::rt::Status st;
    auto out = hal::GpioOutputs::open({chip_, valid_, heartbeat_, active_low, "sempose-test"}, st);
    ASSERT_TRUE(out) << st.message;
    const int inactive = active_low ? 1 : 0;
    EXPECT_EQ(value(valid_), inactive);
    {
      sempose::rt::alloc::ScopedArm arm;
      out->set_pose_valid(true);
      EXPECT_EQ(sempose::rt::alloc::this_thread_allocations(), 0u);
    }
    EXPECT_EQ(value(valid_), 1 - inactive);
    const int hb0 = value(heartbeat_);
    out->toggle_heartbeat();
    EXPECT_NE(value(heartbeat_), hb0);
    out->toggle_heartbeat();
    EXPECT_EQ(value(heartbeat_), hb0);
    out->set_pose_valid(false);
    EXPECT_EQ(value(valid_), inactive);
    EXPECT_EQ(out->write_errors(), 0u);
  }
}

TEST(GpioOpen, MissingChipIsNamedInTheError) {
  sempose::rt::Status st;
  auto sync = hal::GpioFrameSync::open({"nosuchchip7", 0, false, "sempose-test"}, st);
  EXPECT_FALSE(sync);
  EXPECT_NE(st.message.find("nosuchchip7"), std::string::npos) << st.message;
}

// A path that exists and is no chip (a folder) was reported as "No such file or directory"
// (found probing): said as what it is.
TEST(GpioOpen, APathThatIsNoChipIsSaidAsSuch) {
  sempose::rt::Status st;
  auto sync = hal::GpioFrameSync::open({"/tmp", 0, false, "sempose-test"}, st);
  EXPECT_FALSE(sync);
  EXPECT_NE(st.message.find("gpio.chip '/tmp'"), std::string::npos) << st.message;
  EXPECT_NE(st.message.find("it is a folder, not a GPIO chip"), std::string::npos) << st.message;
}
