// The stall rule and the notify protocol, without a pipeline: ProgressMonitor on scripted
// counters and times, SystemdNotifier against a real AF_UNIX datagram socket of the test's own,
// and the heartbeat bit that reports a stall on the bus.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include "sempose/ipc/protocol.hpp"

#include "sempose/service/stage_progress.hpp"
#include "sempose/service/systemd_notify.hpp"

using namespace sempose::service;

namespace {
constexpr std::int64_t kMs = 1'000'000;
}

TEST(ProgressMonitor, MovingCountersAreHealthy) {
  ProgressMonitor m(1000 * kMs, 0);
  for (int i = 1; i <= 50; ++i) {
    const auto n = static_cast<std::uint64_t>(i);
    EXPECT_EQ(m.update(i * 100 * kMs, {n, n, n}, true), 0) << i;
  }
}

TEST(ProgressMonitor, AStageStalledLongerThanTheTimeoutIsFlaggedAlone) {
  ProgressMonitor m(1000 * kMs, 0);
  m.update(100 * kMs, {1, 1, 1}, true);
  // Acquisition keeps scanning, correlation stops making poses (and output has nothing to send).
  EXPECT_EQ(m.update(900 * kMs, {5, 1, 1}, true), 0);               // 0.8 s: not yet
  EXPECT_EQ(m.update(1100 * kMs, {6, 1, 1}, true), kCorrelationStalled | kOutputStalled);
  EXPECT_NE(describe_stall(m.stalled(), m, 1100 * kMs).find("correlation (no pose made for 1.0 s)"), std::string::npos)
      << describe_stall(m.stalled(), m, 1100 * kMs);
  // Progress again: healthy at once.
  EXPECT_EQ(m.update(1200 * kMs, {7, 2, 2}, true), 0);
}

TEST(ProgressMonitor, StartSearchLongerThanAFrameIsNotAStallWithinTheTimeout) {
  ProgressMonitor m(2000 * kMs, 0);
  EXPECT_EQ(m.update(1999 * kMs, {0, 0, 0}, true), 0);  // the first full-field frame is still scanning
  EXPECT_EQ(m.update(2000 * kMs, {0, 0, 0}, true), kAcquisitionStalled | kCorrelationStalled | kOutputStalled);
}

TEST(ProgressMonitor, StoppedOnPurposeIsNotAStall) {
  ProgressMonitor m(1000 * kMs, 0);
  m.update(100 * kMs, {3, 3, 3}, true);
  EXPECT_EQ(m.update(5000 * kMs, {3, 3, 3}, false), 0);  // STOP command: idle on purpose
  EXPECT_EQ(m.update(5500 * kMs, {3, 3, 3}, true), 0);   // START: the clock restarted at the STOP's end
  EXPECT_EQ(m.update(6000 * kMs, {3, 3, 3}, true), kAcquisitionStalled | kCorrelationStalled | kOutputStalled);
}

class NotifySocket : public ::testing::Test {
 protected:
  int fd = -1;
  std::string path;
  void SetUp() override {
    path = "/tmp/sempose_notify_test_" + std::to_string(::getpid());
    ::unlink(path.c_str());
    fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path.c_str());
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    timeval tv{2, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
  void TearDown() override {
    ::close(fd);
    ::unlink(path.c_str());
    ::unsetenv("NOTIFY_SOCKET");
    ::unsetenv("WATCHDOG_USEC");
    ::unsetenv("WATCHDOG_PID");
  }
  std::string receive() {
    char buf[512];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    return n < 0 ? std::string("(nothing)") : std::string(buf, static_cast<std::size_t>(n));
  }
};

TEST_F(NotifySocket, DatagramsReachTheManagersSocket) {
  ::setenv("NOTIFY_SOCKET", path.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "3000000", 1);
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  SystemdNotifier n = SystemdNotifier::from_environment();
  ASSERT_TRUE(n.enabled()) << n.problem();
  EXPECT_EQ(n.watchdog_interval_ns(), 3'000'000'000);
  EXPECT_TRUE(n.ready("running"));
  EXPECT_EQ(receive(), "READY=1\nSTATUS=running");
  EXPECT_TRUE(n.watchdog());
  EXPECT_EQ(receive(), "WATCHDOG=1");
  EXPECT_TRUE(n.stopping());
  EXPECT_EQ(receive(), "STOPPING=1");
}

TEST_F(NotifySocket, WatchdogOfAnotherProcessIsNotOurs) {
  ::setenv("NOTIFY_SOCKET", path.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "3000000", 1);
  ::setenv("WATCHDOG_PID", "1", 1);
  EXPECT_EQ(SystemdNotifier::from_environment().watchdog_interval_ns(), 0);
}

// A WATCHDOG_PID that is not a process id leaves the watchdog unfed (as sd_watchdog_enabled()
// does) and says so: "abc" read as pid 0 was silently "not ours" (hostile round 9).
TEST_F(NotifySocket, AWatchdogPidThatIsNotAProcessIdIsSaid) {
  ::setenv("NOTIFY_SOCKET", path.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "3000000", 1);
  for (const char* pid : {"abc", "", "12x", "-5"}) {
    ::setenv("WATCHDOG_PID", pid, 1);
    SystemdNotifier n = SystemdNotifier::from_environment();
    EXPECT_EQ(n.watchdog_interval_ns(), 0) << pid;
    EXPECT_NE(n.problem().find(std::string("WATCHDOG_PID '") + pid + "' is not a process id"), std::string::npos) << n.problem();
  }
}

TEST_F(NotifySocket, WithoutNotifySocketEverythingIsANoOp) {
  SystemdNotifier n = SystemdNotifier::from_environment();
  EXPECT_FALSE(n.enabled());
  EXPECT_TRUE(n.problem().empty());
  EXPECT_FALSE(n.watchdog());
}

TEST_F(NotifySocket, BadAddressIsReported) {
  ::setenv("NOTIFY_SOCKET", "relative/socket", 1);
  SystemdNotifier n = SystemdNotifier::from_environment();
  EXPECT_FALSE(n.enabled());
  EXPECT_NE(n.problem().find("relative/socket"), std::string::npos);
}

// WATCHDOG_USEC=1 had the main loop send ~95,000 pings in 2.5 s; beyond ~9.2e15 µs the
// nanoseconds overflowed (no pings, no word). Bounded to 20 ms .. 1e12 µs, each end said.
TEST_F(NotifySocket, WatchdogIntervalIsBoundedAndTheBoundSaid) {
  ::setenv("NOTIFY_SOCKET", path.c_str(), 1);
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  ::setenv("WATCHDOG_USEC", "1", 1);
  SystemdNotifier low = SystemdNotifier::from_environment();
  EXPECT_EQ(low.watchdog_interval_ns(), 20'000'000);
  EXPECT_NE(low.problem().find("WATCHDOG_USEC 1 is below 20000"), std::string::npos) << low.problem();
  ::setenv("WATCHDOG_USEC", "9300000000000000", 1);
  SystemdNotifier high = SystemdNotifier::from_environment();
  EXPECT_EQ(high.watchdog_interval_ns(), 1'000'000'000'000'000);
  EXPECT_NE(high.problem().find("beyond 1e12"), std::string::npos) << high.problem();
}

// A NOTIFY_SOCKET nobody listens on: READY cannot be sent, and the caller is told (run said
// "READY sent" regardless, found probing).
TEST_F(NotifySocket, ReadyToASocketNobodyListensOnFails) {
  const std::string gone = path + ".gone";
  ::setenv("NOTIFY_SOCKET", gone.c_str(), 1);
  SystemdNotifier n = SystemdNotifier::from_environment();
  ASSERT_TRUE(n.enabled()) << n.problem();
  EXPECT_FALSE(n.ready("running"));
}

// The heartbeat carries the stall to the bus: bit 7 of byte 0, as ipc/sempose.dbc declares.
TEST(HeartbeatStalledBit, EncodedAtBitSevenAndDeclaredInTheDbc) {
  sempose::ipc::Heartbeat h;
  h.stalled = true;
  std::uint8_t data[8];
  sempose::ipc::encode_heartbeat(h, data);
  EXPECT_EQ(data[0] & 0x80, 0x80);
  sempose::ipc::Heartbeat back;
  ASSERT_TRUE(sempose::ipc::decode_heartbeat(data, 8, back));
  EXPECT_TRUE(back.stalled);
  EXPECT_EQ(back, h);
  h.stalled = false;
  sempose::ipc::encode_heartbeat(h, data);
  EXPECT_EQ(data[0] & 0x80, 0);
  std::ifstream dbc(std::string(SEMPOSE_SOURCE_DIR) + "/ipc/sempose.dbc");
  bool declared = false;
  for (std::string line; std::getline(dbc, line);) declared = declared || line.find(" SG_ stalled : 7|1@1+ (1,0) [0|1]") == 0;
  EXPECT_TRUE(declared);
}
