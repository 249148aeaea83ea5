// The encoder checked against ipc/sempose.dbc: the DBC is parsed here (a tiny reader — Debian 12
// has no python3-cantools), frames from the C++ encoder are decoded by the DBC's signal
// definitions, and the physical values are compared with what was encoded.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include "sempose/ipc/protocol.hpp"

namespace ipc = sempose::ipc;

namespace {

struct DbcSignal {
  std::string name;
  int start = 0;
  int length = 0;
  bool little = true;
  bool is_signed = false;
  double factor = 1;
  double offset = 0;
  double min = 0;
  double max = 0;
  std::string unit;
};

struct DbcMessage {
  std::uint32_t id = 0;
  std::string name;
  int dlc = 0;
  std::map<std::string, DbcSignal> signals;
  std::vector<std::string> order;
};

std::map<std::uint32_t, DbcMessage> load_dbc(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  const std::regex bo(R"(^BO_\s+(\d+)\s+(\w+)\s*:\s*(\d+)\s+(\w+))");
  const std::regex sg(R"(^\s*SG_\s+(\w+)\s*:\s*(\d+)\|(\d+)@([01])([+-])\s*\(([^,]+),([^)]+)\)\s*\[([^|]+)\|([^\]]+)\]\s*"([^"]*)\")");
  std::map<std::uint32_t, DbcMessage> out;
  DbcMessage* cur = nullptr;
  std::string line;
  std::smatch m;
  while (std::getline(in, line)) {
    if (std::regex_search(line, m, bo)) {
      DbcMessage msg;
      msg.id = static_cast<std::uint32_t>(std::stoul(m[1]));
      msg.name = m[2];
      msg.dlc = std::stoi(m[3]);
      cur = &(out[msg.id] = msg);
    } else if (cur != nullptr && std::regex_search(line, m, sg)) {
      DbcSignal s;
      s.name = m[1];
      s.start = std::stoi(m[2]);
      s.length = std::stoi(m[3]);
      s.little = m[4] == "1";
      s.is_signed = m[5] == "-";
      s.factor = std::stod(m[6]);
      s.offset = std::stod(m[7]);
      s.min = std::stod(m[8]);
      s.max = std::stod(m[9]);
      s.unit = m[10];
      cur->order.push_back(s.name);
      cur->signals[s.name] = s;
    } else if (line.find_first_not_of(" \t\r") == std::string::npos) {
      cur = nullptr;
    }
  }
  return out;
}

// Decoding as a DBC tool does it (independent of ipc::get_bits on purpose).
double dbc_decode(const DbcSignal& s, const std::uint8_t* data) {
  EXPECT_TRUE(s.little) << s.name;
  unsigned long long raw = 0;
  for (int i = 0; i < s.length; ++i) {
    const int bit = s.start + i;
    if (data[bit / 8] & (1u << (bit % 8))) raw |= 1ull << i;
  }
  long long value = static_cast<long long>(raw);
  if (s.is_signed && (raw >> (s.length - 1)) & 1u) value -= static_cast<long long>(1ull << s.length);
  return static_cast<double>(value) * s.factor + s.offset;
}

class DbcTest : public ::testing::Test {
 protected:
  void SetUp() override { dbc_ = load_dbc(std::string(SEMPOSE_SOURCE_DIR) + "/ipc/sempose.dbc"); }
  const DbcMessage& msg(std::uint32_t id) {
    auto it = dbc_.find(id);
    if (it == dbc_.end()) {
      ADD_FAILURE() << "id 0x" << std::hex << id << " not in the DBC";
      static DbcMessage empty;
      return empty;
    }
    return it->second;
  }
  double sig(std::uint32_t id, const char* name, const std::uint8_t* data) {
    const auto& m = msg(id);
    auto it = m.signals.find(name);
    if (it == m.signals.end()) {
      ADD_FAILURE() << m.name << " has no signal " << name;
      return std::nan("");
    }
    return dbc_decode(it->second, data);
  }
  std::map<std::uint32_t, DbcMessage> dbc_;
  const ipc::IdMap ids_ = ipc::IdMap::with_base(ipc::kDefaultBaseId);
};

}  // namespace

TEST_F(DbcTest, DescribesEveryFrameWithItsIdAndLength) {
  ASSERT_EQ(dbc_.size(), 4u * 4u + 2u);
  for (int t = 0; t < ipc::kMaxTargets; ++t) {
    EXPECT_EQ(msg(ids_.pose_xy(t)).dlc, 8);
    EXPECT_EQ(msg(ids_.pose_attr(t)).dlc, 8);
    EXPECT_EQ(msg(ids_.pose_unc(t)).dlc, 8);
    EXPECT_EQ(msg(ids_.pose_unc(t)).name, "POSE_UNC_T" + std::to_string(t));
    EXPECT_EQ(msg(ids_.pose_fd(t)).dlc, 64);
    EXPECT_EQ(msg(ids_.pose_xy(t)).name, "POSE_XY_T" + std::to_string(t));
  }
  EXPECT_EQ(msg(ids_.heartbeat()).name, "HEARTBEAT");
  EXPECT_EQ(msg(ids_.command).name, "COMMAND");
  // Units where the value is physical.
  EXPECT_EQ(msg(ids_.pose_xy(0)).signals.at("x").unit, "nm");
  EXPECT_EQ(msg(ids_.pose_attr(0)).signals.at("phi").unit, "deg");
  EXPECT_EQ(msg(ids_.pose_attr(0)).signals.at("age").unit, "us");
  EXPECT_EQ(msg(ids_.heartbeat()).signals.at("dwell").unit, "ns");
  // No two signals of one message overlap, and all fit in the payload.
  for (const auto& [id, m] : dbc_) {
    std::vector<int> owner(static_cast<std::size_t>(m.dlc * 8), 0);
    for (const auto& [name, s] : m.signals) {
      for (int b = s.start; b < s.start + s.length; ++b) {
        ASSERT_LT(b, m.dlc * 8) << m.name << "." << name;
        EXPECT_EQ(owner[static_cast<std::size_t>(b)]++, 0) << m.name << "." << name << " overlaps at bit " << b;
      }
    }
  }
}

TEST_F(DbcTest, ClassicPoseFramesDecodeToTheEncodedValues) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> pos(-5e6, 5e6), ang(-179.999, 180.0), sc(-1.0, 1.0);
  for (int i = 0; i < 500; ++i) {
    ipc::PoseValues p;
    p.x_nm = pos(rng);
    p.y_nm = pos(rng);
    p.phi_deg = ang(rng);
    p.score = sc(rng);
    p.state = static_cast<ipc::WireState>(i % 3);
    p.reason_bits = static_cast<std::uint8_t>(i % 256);
    p.seq = static_cast<std::uint32_t>(i * 7);
    p.age_ns = static_cast<std::int64_t>(i) * 131'071;
    p.look_alike = i % 5 == 0;
    p.angle_order = static_cast<std::uint8_t>(1 + i % 7);
    const int t = i % ipc::kMaxTargets;
    std::uint8_t xy[8], at[8];
    ipc::encode_pose_xy(p, xy);
    ipc::encode_pose_attr(p, at);
    const auto id_xy = ids_.pose_xy(t), id_at = ids_.pose_attr(t);
    EXPECT_NEAR(sig(id_xy, "x", xy), p.x_nm, 0.5);
    EXPECT_NEAR(sig(id_xy, "y", xy), p.y_nm, 0.5);
    EXPECT_EQ(sig(id_xy, "seq", xy), p.seq % 256);
    EXPECT_NEAR(sig(id_at, "phi", at), p.phi_deg, 0.0005 + 1e-9);
    EXPECT_NEAR(sig(id_at, "score", at), p.score, 0.0005 + 1e-9);
    EXPECT_EQ(sig(id_at, "state", at), i % 3);
    EXPECT_EQ(sig(id_at, "reason", at), i % 256);
    EXPECT_EQ(sig(id_at, "seq", at), p.seq % 256);
    EXPECT_NEAR(sig(id_at, "age", at), std::min<double>(p.age_ns / 1000.0, 32760), 4 + 1e-9) << "8 µs steps, rounded";
    EXPECT_EQ(sig(id_at, "angle_order", at), 1 + i % 7);
    EXPECT_EQ(sig(id_at, "look_alike", at), i % 5 == 0 ? 1 : 0) << "the flag sits in the age's old top bit";
  }
}

// The uncertainty frame as the DBC reads it, at the wire's resolution, saturating inside its ranges.
TEST_F(DbcTest, UncertaintyFrameDecodesToTheEncodedValues) {
  std::mt19937 rng(99);
  std::uniform_real_distribution<double> sxy(0, 400), sphi(0, 2.0), scale(0.6, 2.1), sscale(0, 0.06);
  for (int i = 0; i < 300; ++i) {
    ipc::PoseValues p;
    p.sigma_x_nm = sxy(rng);
    p.sigma_y_nm = sxy(rng);
    p.sigma_phi_deg = sphi(rng);
    p.target_scale = scale(rng);
    p.sigma_scale = sscale(rng);
    p.seq = static_cast<std::uint32_t>(i * 5);
    std::uint8_t d[8];
    ipc::encode_pose_unc(p, d);
    const auto id = ids_.pose_unc(i % ipc::kMaxTargets);
    EXPECT_NEAR(sig(id, "sigma_x", d), p.sigma_x_nm, 0.05 + 1e-9);
    EXPECT_NEAR(sig(id, "sigma_y", d), p.sigma_y_nm, 0.05 + 1e-9);
    EXPECT_NEAR(sig(id, "sigma_phi", d), p.sigma_phi_deg, 0.0005 + 1e-9);
    EXPECT_NEAR(sig(id, "target_scale", d), p.target_scale, 0.00005 + 1e-9);
    EXPECT_NEAR(sig(id, "sigma_scale", d), p.sigma_scale, 0.00025 + 1e-9);
    EXPECT_EQ(sig(id, "seq", d), p.seq % 256);
  }
  ipc::PoseValues big;
  big.sigma_x_nm = 1e6;
  big.sigma_y_nm = -5;
  big.sigma_phi_deg = 45;
  big.target_scale = 9;
  big.sigma_scale = 1;
  std::uint8_t d[8];
  ipc::encode_pose_unc(big, d);
  const auto& m = msg(ids_.pose_unc(0));
  for (const auto& name : m.order) {
    const auto& sg = m.signals.at(name);
    const double v = dbc_decode(sg, d);
    EXPECT_GE(v, sg.min - 1e-9) << name;
    EXPECT_LE(v, sg.max + 1e-9) << name;
  }
  EXPECT_NEAR(sig(ids_.pose_unc(0), "sigma_x", d), 409.5, 1e-9);
  EXPECT_EQ(sig(ids_.pose_unc(0), "sigma_y", d), 0);
  EXPECT_NEAR(sig(ids_.pose_unc(0), "target_scale", d), 2.1383, 1e-9);
}

TEST_F(DbcTest, SaturatedValuesStayInsideTheDbcRanges) {
  ipc::PoseValues p;
  p.x_nm = 1e15;
  p.y_nm = -1e15;
  p.score = -9;
  p.phi_deg = 180;
  p.age_ns = 1'000'000'000'000;
  std::uint8_t xy[8], at[8];
  ipc::encode_pose_xy(p, xy);
  ipc::encode_pose_attr(p, at);
  const auto& mxy = msg(ids_.pose_xy(0));
  const auto& mat = msg(ids_.pose_attr(0));
  for (const auto& name : mxy.order) {
    const auto& s = mxy.signals.at(name);
    const double v = dbc_decode(s, xy);
    EXPECT_GE(v, s.min) << name;
    EXPECT_LE(v, s.max) << name;
  }
  for (const auto& name : mat.order) {
    const auto& s = mat.signals.at(name);
    const double v = dbc_decode(s, at);
    EXPECT_GE(v, s.min - 1e-9) << name;
    EXPECT_LE(v, s.max + 1e-9) << name;
  }
  EXPECT_EQ(sig(ids_.pose_xy(0), "x", xy), mxy.signals.at("x").max);
  EXPECT_EQ(sig(ids_.pose_xy(0), "y", xy), mxy.signals.at("y").min);
}

TEST_F(DbcTest, FdPoseFrameDecodesToTheEncodedValues) {
  ipc::PoseValues p;
  p.x_nm = -1234567.4;
  p.y_nm = 3e9;  // beyond int32: saturates
  p.phi_deg = 91.2345;
  p.score = -0.12345;
  p.psr = 17.25;
  p.state = ipc::WireState::kLost;
  p.reason_bits = 0x22;
  p.seq = 0xDEADBEEF;
  p.age_ns = 77'000'999;
  p.pattern_set = 7;
  p.target = 1;
  p.dwell_ns = 300;
  p.frame_seq = 123456789;
  p.nm_per_px = 40.125;
  p.target_scale = 1.23456;
  p.sigma_x_nm = 3.217;
  p.sigma_y_nm = 4.5;
  p.sigma_phi_deg = 0.123456;
  p.sigma_scale = 0.001234;
  p.reason_bits = 0xA2;  // bit 7: unexplained
  p.angle_order = 4;
  std::uint8_t d[64];
  ipc::encode_pose_fd(p, d);
  const auto id = ids_.pose_fd(1);
  EXPECT_EQ(sig(id, "x", d), -1234567);
  EXPECT_EQ(sig(id, "y", d), 2147483647);
  EXPECT_NEAR(sig(id, "phi", d), 91.2345, 0.0005 + 1e-9);
  EXPECT_NEAR(sig(id, "score", d), -0.1235, 0.00005 + 1e-9);
  EXPECT_NEAR(sig(id, "psr", d), 17.25, 1e-9);
  EXPECT_EQ(sig(id, "state", d), 2);
  EXPECT_EQ(sig(id, "reason", d), 0xA2);
  EXPECT_EQ(sig(id, "seq", d), 0xDEADBEEF);
  EXPECT_EQ(sig(id, "age", d), 77000);
  EXPECT_EQ(sig(id, "pattern_set", d), 7);
  EXPECT_EQ(sig(id, "target", d), 1);
  EXPECT_EQ(sig(id, "dwell", d), 300);
  EXPECT_EQ(sig(id, "frame_seq", d), 123456789);
  EXPECT_NEAR(sig(id, "scale", d), 40.125, 1e-9);
  EXPECT_NEAR(sig(id, "target_scale", d), 1.2346, 1e-9);
  EXPECT_NEAR(sig(id, "sigma_x", d), 3.217, 1e-9);
  EXPECT_NEAR(sig(id, "sigma_y", d), 4.5, 1e-9);
  EXPECT_NEAR(sig(id, "sigma_phi", d), 0.123456, 1e-9);
  EXPECT_NEAR(sig(id, "sigma_scale", d), 0.001234, 1e-9);
  EXPECT_EQ(sig(id, "angle_order", d), 4);
}

// A wire-format change bumps both ipc::kWireVersion and the DBC's VERSION (make_dbc.py).
TEST_F(DbcTest, VersionStringMatchesTheProtocol) {
  std::ifstream in(std::string(SEMPOSE_SOURCE_DIR) + "/ipc/sempose.dbc");
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, "VERSION \"sempose-" + std::to_string(ipc::kWireVersion) + "\"");
}

TEST_F(DbcTest, HeartbeatAndCommandDecodeByTheDbc) {
  ipc::Heartbeat h;
  h.state = ipc::WireState::kAcquiring;
  h.running = true;
  h.bus_state = ipc::BusState::kPassive;
  h.fd = false;
  h.pattern_set = 5;
  h.bad_commands = 2;
  h.counter = 200;
  h.last_command_seq = 42;
  h.dwell_ns = 250;
  h.dropped_frames = 17;
  h.overruns = 3;
  h.tx_dropped = 9;
  std::uint8_t d[8];
  ipc::encode_heartbeat(h, d);
  const auto hb = ids_.heartbeat();
  EXPECT_EQ(sig(hb, "state", d), 1);
  EXPECT_EQ(sig(hb, "running", d), 1);
  EXPECT_EQ(sig(hb, "bus_state", d), 1);
  EXPECT_EQ(sig(hb, "fd", d), 0);
  EXPECT_EQ(sig(hb, "pattern_set", d), 5);
  EXPECT_EQ(sig(hb, "bad_commands", d), 2);
  EXPECT_EQ(sig(hb, "counter", d), 200);
  EXPECT_EQ(sig(hb, "last_command_seq", d), 42);
  EXPECT_EQ(sig(hb, "dwell", d), 250);
  EXPECT_EQ(sig(hb, "dropped_frames", d), 17);
  EXPECT_EQ(sig(hb, "overruns", d), 3);
  EXPECT_EQ(sig(hb, "tx_dropped", d), 9);

  const ipc::WireCommand c{ipc::Opcode::kSelectPatternSet, 9, 4, 41250};
  ipc::encode_command(c, d);
  EXPECT_EQ(sig(ids_.command, "opcode", d), 1);
  EXPECT_EQ(sig(ids_.command, "seq", d), 9);
  EXPECT_EQ(sig(ids_.command, "arg", d), 4);
  EXPECT_EQ(sig(ids_.command, "reserved", d), 0);
  EXPECT_NEAR(sig(ids_.command, "scale", d), 41.25, 1e-9);
}
