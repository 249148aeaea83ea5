// SocketCanChannel + CanPoseSink against a real SocketCAN interface (vcan or a real bus).
//   SEMPOSE_CAN=vcan0 ./can_gpio_hw_test       (the interface must exist and be up)
// Without SEMPOSE_CAN the test uses vcan0 if it exists, else tries to create a private vcan
// (root + vcan module); when the kernel has no CAN support every test skips, saying why.
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "sempose/can_output/can_pose_sink.hpp"
#include "sempose/hal/can_socket_channel.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace co = sempose::can_output;
namespace hal = sempose::hal;
namespace ipc = sempose::ipc;
namespace pl = sempose::pipeline;

namespace {

constexpr const char* kPrivateVcan = "semposevcan0";

// Picks the interface once per process; returns "" with the reason when there is none.
const std::string& can_interface(std::string& why) {
  static std::string name;
  static std::string reason;
  static bool done = false;
  if (!done) {
    done = true;
    const char* env = std::getenv("SEMPOSE_CAN");
    if (env != nullptr && *env != '\0') {
      name = env;
      if (if_nametoindex(env) == 0) reason = std::string("SEMPOSE_CAN=") + env + ": no such interface";
    } else if (if_nametoindex("vcan0") != 0) {
      name = "vcan0";
    } else if (std::system((std::string("ip link add dev ") + kPrivateVcan + " type vcan 2>/dev/null && ip link set " +
                            kPrivateVcan + " up 2>/dev/null").c_str()) == 0) {
      name = kPrivateVcan;
      std::atexit([] { (void)std::system((std::string("ip link del ") + kPrivateVcan + " 2>/dev/null").c_str()); });
    } else {
      reason = "no CAN interface: `ip link add dev vcan0 type vcan` failed (this kernel has no CAN/vcan support, "
               "or not root); set SEMPOSE_CAN=<interface> on a host that has one — the system test runs this "
               "binary inside a PREEMPT_RT VM with vcan";
    }
    if (!reason.empty()) name.clear();
  }
  why = reason;
  return name;
}

// The test's own raw socket: plays the controller (receives poses, sends commands).
class Peer {
 public:
  explicit Peer(const std::string& ifname) {
    sock_ = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
    const int on = 1;
    ::setsockopt(sock_, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(if_nametoindex(ifname.c_str()));
    ok_ = sock_ >= 0 && ::bind(sock_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  }
  ~Peer() {
    if (sock_ >= 0) ::close(sock_);
  }
  bool ok() const { return ok_; }
  bool receive(canfd_frame& f, int timeout_ms = 1000) {
    pollfd p{sock_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return false;
    const ssize_t n = ::recv(sock_, &f, sizeof f, 0);
    return n == CAN_MTU || n == CANFD_MTU;
  }
  bool send(std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
    can_frame f{};
    f.can_id = id;
    for (auto b : bytes) f.data[f.can_dlc++] = b;
    return ::write(sock_, &f, CAN_MTU) == CAN_MTU;
  }

 private:
  int sock_ = -1;
  bool ok_ = false;
};

class SocketCanTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    ifname_ = can_interface(why);
    if (ifname_.empty()) GTEST_SKIP() << why;
  }
  std::unique_ptr<hal::SocketCanChannel> open(hal::CanFdMode fd = hal::CanFdMode::kOff) {
    hal::SocketCanOptions o;
    o.interface = ifname_;
    o.fd = fd;
    o.rx_id = 0x150;
    sempose::rt::Status st;
    auto ch = hal::SocketCanChannel::open(o, st);
    EXPECT_TRUE(ch) << st.message;
    return ch;
  }
  std::string ifname_;
};

pl::PoseRecord pose(std::uint32_t seq) {
  pl::PoseRecord p;
  p.target = 0;
  p.pose_seq = seq;
  p.state = sempose::pose::TrackState::kTracking;
  p.x_px = 10 + seq;
  p.y_px = -2;
  p.nm_per_px = 50;
  return p;
}

}  // namespace

TEST_F(SocketCanTest, PosesAndHeartbeatReachAnotherSocket) {
  Peer peer(ifname_);
  ASSERT_TRUE(peer.ok());
  auto ch = open();
  ASSERT_TRUE(ch);
  co::CanPoseSink sink(*ch, {});
  // Few enough that the peer's default receive buffer holds them all (no reader thread here):
  // three classic frames per pose (XY, ATTR, POSE_UNC) plus a heartbeat.
  constexpr std::uint32_t kPoses = 60;
  for (std::uint32_t i = 0; i < kPoses; ++i) ASSERT_EQ(sink.publish(pose(i), 0), pl::PublishResult::kSent) << i;
  sink.service({}, 0);  // first heartbeat
  for (std::uint32_t i = 0; i < kPoses; ++i) {
    canfd_frame xy{}, at{}, un{};
    ASSERT_TRUE(peer.receive(xy)) << "pose " << i << " XY not received";
    ASSERT_TRUE(peer.receive(at)) << "pose " << i << " ATTR not received";
    ASSERT_TRUE(peer.receive(un)) << "pose " << i << " POSE_UNC not received";
    EXPECT_EQ(xy.can_id, 0x100u);
    EXPECT_EQ(at.can_id, 0x101u);
    EXPECT_EQ(un.can_id, 0x103u);
    ipc::PoseUnc u;
    ASSERT_TRUE(ipc::decode_pose_unc(un.data, un.len, u));
    EXPECT_EQ(u.seq, i % 256);
    ipc::PoseXy d;
    ASSERT_TRUE(ipc::decode_pose_xy(xy.data, xy.len, d));
    EXPECT_EQ(d.seq, i % 256);
    EXPECT_EQ(d.x_nm, static_cast<std::int32_t>((10 + i) * 50));
    EXPECT_EQ(d.y_nm, -100);
  }
  canfd_frame hb{};
  ASSERT_TRUE(peer.receive(hb));
  EXPECT_EQ(hb.can_id, 0x140u);
  EXPECT_EQ(ch->bus_state(), hal::CanBusState::kActive);
  EXPECT_EQ(ch->counters().tx_frames.load(), 3 * kPoses + 1);
}

TEST_F(SocketCanTest, CommandsAreReadWithoutBlockingAndValidated) {
  Peer peer(ifname_);
  ASSERT_TRUE(peer.ok());
  auto ch = open();
  ASSERT_TRUE(ch);
  co::CanPoseSink sink(*ch, {});
  sink.service({}, 0);  // nothing pending: returns at once
  ASSERT_TRUE(peer.send(0x150, {1, 7, 2, 0, 0x40, 0x9C, 0, 0}));  // select set 2, 40 nm/px
  ASSERT_TRUE(peer.send(0x150, {9, 8, 0, 0, 0, 0, 0, 0}));        // unknown opcode
  ASSERT_TRUE(peer.send(0x150, {2, 9, 0}));                       // short frame
  ASSERT_TRUE(peer.send(0x123, {2, 9, 0, 0, 0, 0, 0, 0}));        // not the command id: filtered by the kernel
  ::usleep(20000);
  sink.service({}, 1);
  pl::Command c;
  ASSERT_TRUE(sink.next_command(c));
  EXPECT_EQ(c.kind, pl::CommandKind::kSelectPatternSet);
  EXPECT_EQ(c.arg, 2);
  EXPECT_DOUBLE_EQ(c.nm_per_px, 40.0);
  EXPECT_FALSE(sink.next_command(c));
  EXPECT_EQ(sink.counters().bad_commands.load(), 2u);
  EXPECT_EQ(sink.counters().non_command_frames.load(), 0u);
  EXPECT_EQ(sink.counters().last_command_seq.load(), 7);
}

TEST_F(SocketCanTest, SendAndServiceDoNotAllocateOrBlock) {
  auto ch = open();
  ASSERT_TRUE(ch);
  co::CanPoseSink sink(*ch, {});
  pl::PipelineStatus s;
  std::uint64_t attempts = 0;
  {
    sempose::rt::alloc::ScopedArm arm;
    for (std::uint32_t i = 0; i < 2000; ++i) {
      sink.publish(pose(i), i);
      sink.service(s, static_cast<std::int64_t>(i) * 1'000'000);
      ++attempts;
    }
    EXPECT_EQ(sempose::rt::alloc::this_thread_allocations(), 0u);
  }
  const auto& c = sink.counters();
  EXPECT_EQ(c.poses_sent.load() + c.poses_dropped.load(), attempts) << "every pose sent or counted";
}

TEST_F(SocketCanTest, FdWhenTheMtuAllowsIt) {
  auto probe = open();
  ASSERT_TRUE(probe);
  if (probe->mtu() != CANFD_MTU) GTEST_SKIP() << ifname_ << " has MTU " << probe->mtu() << ", not 72: no CAN FD";
  probe.reset();
  Peer peer(ifname_);
  auto ch = open(hal::CanFdMode::kAuto);
  ASSERT_TRUE(ch && ch->fd_enabled());
  co::CanPoseSink sink(*ch, {});
  ASSERT_EQ(sink.publish(pose(77), 0), pl::PublishResult::kSent);
  canfd_frame f{};
  ASSERT_TRUE(peer.receive(f));
  EXPECT_EQ(f.can_id, 0x102u);
  EXPECT_EQ(f.len, 64);
  ipc::PoseFd d;
  ASSERT_TRUE(ipc::decode_pose_fd(f.data, f.len, d));
  EXPECT_EQ(d.seq, 77u);
}

TEST(SocketCanOpen, UnknownInterfaceIsNamedInTheError) {
  hal::SocketCanOptions o;
  o.interface = "nosuchcan9";
  sempose::rt::Status st;
  auto ch = hal::SocketCanChannel::open(o, st);
  EXPECT_FALSE(ch);
  EXPECT_NE(st.message.find("nosuchcan9"), std::string::npos) << st.message;
}

// An interface that goes away and comes back (`ip link del`, a USB-CAN adapter unplugged and
// plugged in again) gets a new ifindex: the channel must mark itself detached, count what it
// cannot send, and bind again from flush() — so poses reach the bus after the interface is
// back and commands are read again. Needs its own vcan (the one under test is not deleted).
TEST(SocketCanRebind, InterfaceDeletedAndCreatedAgainIsBoundAgain) {
  constexpr const char* kIf = "semposerb0";
  const std::string add = std::string("ip link add dev ") + kIf + " type vcan 2>/dev/null && ip link set " + kIf + " up";
  const std::string del = std::string("ip link del ") + kIf + " 2>/dev/null";
  (void)std::system(del.c_str());
  if (std::system(add.c_str()) != 0)
    GTEST_SKIP() << "cannot create vcan " << kIf << " (no CAN/vcan support in this kernel, or not root)";
  struct Cleanup {
    std::string cmd;
    ~Cleanup() { (void)std::system(cmd.c_str()); }
  } cleanup{del};

  hal::SocketCanOptions o;
  o.interface = kIf;
  o.rx_id = 0x150;
  sempose::rt::Status st;
  auto ch = hal::SocketCanChannel::open(o, st);
  ASSERT_TRUE(ch) << st.message;
  co::CanPoseSink sink(*ch, {});
  {
    Peer peer(kIf);
    ASSERT_TRUE(peer.ok());
    ASSERT_EQ(sink.publish(pose(1), 0), pl::PublishResult::kSent);
    canfd_frame f{};
    ASSERT_TRUE(peer.receive(f));
  }
  EXPECT_FALSE(ch->detached());

  ASSERT_EQ(std::system(del.c_str()), 0);
  // Sends fail (counted), the channel says it is detached, receive() does not block or spin.
  EXPECT_NE(sink.publish(pose(2), 0), pl::PublishResult::kSent);
  hal::CanFrame in;
  EXPECT_FALSE(ch->receive(in));
  EXPECT_TRUE(ch->detached());
  const auto errors = ch->counters().tx_errors.load();
  EXPECT_GE(errors, 1u);
  ch->flush();  // the interface is still gone: stays detached, says why
  EXPECT_TRUE(ch->detached());
  EXPECT_NE(ch->rebind_status().message.find(kIf), std::string::npos) << ch->rebind_status().message;
  EXPECT_EQ(ch->counters().rebinds.load(), 0u);

  ASSERT_EQ(std::system(add.c_str()), 0);
  ch->flush();
  EXPECT_FALSE(ch->detached()) << ch->rebind_status().message;
  EXPECT_EQ(ch->counters().rebinds.load(), 1u);
  Peer peer(kIf);
  ASSERT_TRUE(peer.ok());
  ASSERT_EQ(sink.publish(pose(3), 0), pl::PublishResult::kSent);
  canfd_frame f{};
  ASSERT_TRUE(peer.receive(f));
  ipc::PoseXy xy;
  ASSERT_TRUE(ipc::decode_pose_xy(f.data, f.len, xy));
  // Commands reach the re-bound socket with its filter: only the command id.
  ASSERT_TRUE(peer.send(0x7FF, {1, 2}));
  ASSERT_TRUE(peer.send(0x150, {0x03, 0x05, 0, 0, 0, 0, 0, 0}));  // STOP seq 5
  bool got = false;
  for (int i = 0; i < 100 && !got; ++i) {
    got = ch->receive(in);
    if (!got) ::usleep(10'000);
  }
  ASSERT_TRUE(got);
  EXPECT_EQ(in.id, 0x150u);
}
