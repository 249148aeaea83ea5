// candump -l log channel: exact line format (classic, extended, RTR, FD), the RT path does not
// allocate, a full ring drops and counts, and python-can's CanutilsLogReader reads the file
// back (decoded by ipc/sempose.dbc through ipc/tools/sempose_dbc.py).
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "sempose/hal/can_candump_log.hpp"
#include "sempose/ipc/protocol.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace hal = sempose::hal;
namespace ipc = sempose::ipc;

namespace {

hal::CanFrame frame(std::uint32_t id, std::initializer_list<std::uint8_t> bytes, std::uint8_t flags = 0) {
  hal::CanFrame f;
  f.id = id;
  f.flags = flags;
  for (auto b : bytes) f.data[f.len++] = b;
  return f;
}

std::string line(const hal::CanFrame& f, std::int64_t t_ns, const char* ch = "can0") {
  char buf[hal::CandumpLogChannel::kMaxLine];
  const auto n = hal::CandumpLogChannel::format_line(f, t_ns, ch, buf);
  return std::string(buf, n);
}

std::string temp_path(const char* name) {
  return ::testing::TempDir() + "sempose_" + name + "_" + std::to_string(::getpid()) + ".log";
}

std::string read_all(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST(CandumpFormat, ClassicExtendedRemoteAndFdLines) {
  EXPECT_EQ(line(frame(0x123, {0xDE, 0xAD, 0xBE, 0xEF}), 1'600'000'000'123'456'789),
            "(1600000000.123456) can0 123#DEADBEEF\n");
  EXPECT_EQ(line(frame(0x7, {}), 5'000), "(0000000000.000005) can0 007#\n");
  EXPECT_EQ(line(frame(0x1ABCDEF, {0x01}, hal::CanFrame::kExtended), 1'000'000'000, "vcan0"),
            "(0000000001.000000) vcan0 01ABCDEF#01\n");
  EXPECT_EQ(line(frame(0x55, {}, hal::CanFrame::kRemote), 0), "(0000000000.000000) can0 055#R\n");
  hal::CanFrame fd = frame(0x102, {}, hal::CanFrame::kFd);
  fd.len = 64;
  for (int i = 0; i < 64; ++i) fd.data[i] = static_cast<std::uint8_t>(i);
  const std::string l = line(fd, 2'000'000'000);
  EXPECT_EQ(l.substr(0, 31), "(0000000002.000000) can0 102##0");
  EXPECT_EQ(l.size(), 31u + 128u + 1u);
  EXPECT_EQ(l.substr(31, 8), "00010203");
  fd.flags |= hal::CanFrame::kBrs;
  EXPECT_EQ(line(fd, 0).substr(25, 6), "102##1");
  EXPECT_LE(l.size(), hal::CandumpLogChannel::kMaxLine);
}

TEST(CandumpLog, SendDoesNotAllocateAndFlushWritesEverything) {
  const auto path = temp_path("noalloc");
  sempose::rt::Status st;
  auto ch = hal::CandumpLogChannel::open({path, "can0", 1 << 16, false, true}, st);
  ASSERT_TRUE(ch) << st.message;
  const auto f = frame(0x100, {1, 2, 3, 4, 5, 6, 7, 8});
  hal::CanFrame fd = frame(0x102, {}, hal::CanFrame::kFd);
  fd.len = 64;
  {
    sempose::rt::alloc::ScopedArm arm;
    for (int i = 0; i < 100; ++i) ASSERT_EQ(ch->send(f, i * 1000), hal::CanSendResult::kSent);
    ASSERT_EQ(ch->send(fd, 0), hal::CanSendResult::kSent);
    EXPECT_EQ(sempose::rt::alloc::this_thread_allocations(), 0u);
  }
  ch->flush();
  const std::string text = read_all(path);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 101);
  EXPECT_NE(text.find("(0000000000.000099) can0 100#0102030405060708\n"), std::string::npos);
  EXPECT_EQ(ch->counters().tx_frames.load(), 101u);
  std::remove(path.c_str());
}

TEST(CandumpLog, FullRingDropsAndCountsInsteadOfBlocking) {
  const auto path = temp_path("overflow");
  sempose::rt::Status st;
  auto ch = hal::CandumpLogChannel::open({path, "can0", 4096, false, false}, st);
  ASSERT_TRUE(ch) << st.message;
  const auto f = frame(0x100, {1, 2, 3, 4, 5, 6, 7, 8});
  const int line_bytes = static_cast<int>(line(f, 0).size());
  ASSERT_EQ(line_bytes, 46);
  int sent = 0, dropped = 0;
  for (int i = 0; i < 200; ++i) (ch->send(f, 0) == hal::CanSendResult::kSent ? sent : dropped)++;
  EXPECT_EQ(sent, 4096 / line_bytes);
  EXPECT_EQ(dropped, 200 - sent);
  EXPECT_EQ(ch->counters().tx_dropped.load(), static_cast<std::uint64_t>(dropped));
  ch->flush();  // room again
  EXPECT_EQ(ch->send(f, 0), hal::CanSendResult::kSent);
  // FD frames are refused by a classic log (counted as errors, not silently truncated).
  hal::CanFrame fd = frame(0x102, {}, hal::CanFrame::kFd);
  EXPECT_EQ(ch->send(fd, 0), hal::CanSendResult::kError);
  ch.reset();  // flushes: what was accepted is in the file, nothing else
  const std::string text = read_all(path);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), sent + 1);
  std::remove(path.c_str());
}

// The log deleted mid-run (an operator cleaning the output folder): what is written after
// that reaches nobody and must be a reported loss, not taken as written.
TEST(CandumpLog, WritingIntoADeletedLogIsAWriteErrorAndCountedLost) {
  const auto path = temp_path("deleted");
  sempose::rt::Status st;
  auto ch = hal::CandumpLogChannel::open({path, "can0", 4096, false, false}, st);
  ASSERT_TRUE(ch) << st.message;
  const auto f = frame(0x100, {1, 2, 3, 4, 5, 6, 7, 8});
  ASSERT_EQ(ch->send(f, 0), hal::CanSendResult::kSent);
  ch->flush();
  ASSERT_EQ(ch->write_errors(), 0u);
  ASSERT_EQ(std::remove(path.c_str()), 0);
  for (int i = 0; i < 3; ++i) ASSERT_EQ(ch->send(f, 0), hal::CanSendResult::kSent);
  ch->flush();
  EXPECT_EQ(ch->write_errors(), 1u);
  EXPECT_EQ(ch->last_errno(), ENOENT);
  EXPECT_EQ(ch->bytes_lost_to_deleted_file(), 3u * line(f, 0).size());
  ch->flush();
  EXPECT_EQ(ch->write_errors(), 1u) << "nothing new written: no new error";
}

TEST(CandumpLog, OpenFailureNamesThePath) {
  sempose::rt::Status st;
  auto ch = hal::CandumpLogChannel::open({"/nonexistent-dir/x.log", "can0", 4096, false, false}, st);
  EXPECT_FALSE(ch);
  EXPECT_NE(st.message.find("/nonexistent-dir/x.log"), std::string::npos) << st.message;
}

// The log as other tools see it: python-can reads it, the DBC decodes it.
TEST(CandumpLog, PythonCanReadsItAndTheDbcDecodesIt) {
  if (std::system(SEMPOSE_PYTHON " -c 'import can' 2>/dev/null") != 0)
    GTEST_SKIP() << "python3-can is not installed (apt-get install python3-can)";
  const auto path = temp_path("pycan");
  sempose::rt::Status st;
  auto ch = hal::CandumpLogChannel::open({path, "can0", 1 << 16, false, true}, st);
  ASSERT_TRUE(ch) << st.message;
  const auto ids = ipc::IdMap::with_base(ipc::kDefaultBaseId);
  std::vector<ipc::PoseValues> poses;
  for (int i = 0; i < 20; ++i) {
    ipc::PoseValues p;
    p.x_nm = -50'000.0 + 1234.5 * i;
    p.y_nm = 700.25 * i;
    p.phi_deg = -170.0 + 17.3 * i;
    p.score = 0.05 * i - 0.2;
    p.seq = static_cast<std::uint32_t>(250 + i);  // wraps through 255 -> 0
    p.age_ns = 8000 * i;  // the classic age's 8 µs steps
    p.angle_order = static_cast<std::uint8_t>(1 + i % 7);
    p.state = static_cast<ipc::WireState>(i % 3);
    poses.push_back(p);
    hal::CanFrame xy, at;
    xy.id = ids.pose_xy(0);
    at.id = ids.pose_attr(0);
    xy.len = at.len = 8;
    ipc::encode_pose_xy(p, xy.data);
    ipc::encode_pose_attr(p, at.data);
    ASSERT_EQ(ch->send(xy, 1'000'000'000LL + i * 10'000'000LL), hal::CanSendResult::kSent);
    ASSERT_EQ(ch->send(at, 1'000'000'000LL + i * 10'000'000LL), hal::CanSendResult::kSent);
  }
  hal::CanFrame fd;
  fd.id = ids.pose_fd(1);
  fd.len = 64;
  fd.flags = hal::CanFrame::kFd;
  ipc::encode_pose_fd(poses[3], fd.data);
  ASSERT_EQ(ch->send(fd, 2'000'000'000), hal::CanSendResult::kSent);
  ch.reset();  // flush + close

  const std::string cmd = std::string(SEMPOSE_PYTHON " ") + SEMPOSE_SOURCE_DIR + "/ipc/tools/sempose_dbc.py " +
                          SEMPOSE_SOURCE_DIR + "/ipc/sempose.dbc " + path;
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::vector<std::string> lines;
  char buf[1024];
  while (std::fgets(buf, sizeof buf, p) != nullptr) lines.emplace_back(buf);
  ASSERT_EQ(::pclose(p), 0) << cmd;
  ASSERT_EQ(lines.size(), 41u);
  auto value = [](const std::string& l, const std::string& key) {
    const auto pos = l.find(" " + key + "=");
    EXPECT_NE(pos, std::string::npos) << key << " missing in: " << l;
    return pos == std::string::npos ? 0.0 : std::stod(l.substr(pos + key.size() + 2));
  };
  for (int i = 0; i < 20; ++i) {
    const auto& lxy = lines[static_cast<std::size_t>(2 * i)];
    const auto& lat = lines[static_cast<std::size_t>(2 * i + 1)];
    EXPECT_NE(lxy.find(" 100 CC POSE_XY_T0 "), std::string::npos) << lxy;
    EXPECT_NE(lat.find(" 101 CC POSE_ATTR_T0 "), std::string::npos) << lat;
    EXPECT_NEAR(std::stod(lxy), 1.0 + i * 0.01, 1e-6) << "timestamp";
    EXPECT_NEAR(value(lxy, "x"), poses[i].x_nm, 0.5);
    EXPECT_NEAR(value(lxy, "y"), poses[i].y_nm, 0.5);
    EXPECT_NEAR(value(lat, "phi"), poses[i].phi_deg, 0.0005);
    EXPECT_NEAR(value(lat, "score"), poses[i].score, 0.0005);
    EXPECT_EQ(value(lat, "state"), i % 3);
    EXPECT_EQ(value(lxy, "seq"), (250 + i) % 256);
    EXPECT_EQ(value(lat, "seq"), value(lxy, "seq"));
    EXPECT_EQ(value(lat, "age"), 8 * i);
    EXPECT_EQ(value(lat, "angle_order"), 1 + i % 7);
  }
  EXPECT_NE(lines[40].find(" 112 FD POSE_FD_T1 "), std::string::npos) << lines[40];
  EXPECT_NEAR(value(lines[40], "x"), poses[3].x_nm, 0.5);
  EXPECT_EQ(value(lines[40], "seq"), 253);
  std::remove(path.c_str());
}
