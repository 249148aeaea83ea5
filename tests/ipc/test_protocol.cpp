// Wire protocol: round trips, saturation, negative values, counter wrap, command validation,
// and no heap use on the encode/decode path.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "sempose/ipc/protocol.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace ipc = sempose::ipc;

namespace {

ipc::PoseValues sample_pose() {
  ipc::PoseValues p;
  p.x_nm = 12345.4;
  p.y_nm = -6789.6;
  p.phi_deg = -37.1234;
  p.score = 0.8765;
  p.psr = 12.34;
  p.state = ipc::WireState::kTracking;
  p.reason_bits = 0;
  p.seq = 0x1234;
  p.age_ns = 2'345'678;
  p.pattern_set = 3;
  p.target = 2;
  p.dwell_ns = 250;
  p.frame_seq = 0x1'0000'0042ull;
  p.nm_per_px = 39.5;
  return p;
}

// p encoded as POSE_ATTR and as POSE_FD, each decoded back.
std::pair<ipc::PoseAttr, ipc::PoseFd> through_attr_and_fd(const ipc::PoseValues& p) {
  std::uint8_t attr[8], fd[64];
  ipc::encode_pose_attr(p, attr);
  ipc::encode_pose_fd(p, fd);
  std::pair<ipc::PoseAttr, ipc::PoseFd> out;
  EXPECT_TRUE(ipc::decode_pose_attr(attr, 8, out.first));
  EXPECT_TRUE(ipc::decode_pose_fd(fd, 64, out.second));
  return out;
}

}  // namespace

TEST(BitPack, SignedFieldsRoundTripAcrossByteBoundaries) {
  std::uint8_t d[8]{};
  for (std::int64_t v : {-134217728ll, -1ll, 0ll, 1ll, 134217727ll}) {
    ipc::put_bits(d, 28, 28, static_cast<std::uint64_t>(v));
    EXPECT_EQ(ipc::get_signed_bits(d, 28, 28), v);
  }
  // Neighbouring fields are untouched.
  std::memset(d, 0, sizeof d);
  ipc::put_bits(d, 0, 28, 0xFFFFFFF);
  ipc::put_bits(d, 56, 8, 0);
  ipc::put_bits(d, 28, 28, 0);
  EXPECT_EQ(ipc::get_bits(d, 0, 28), 0xFFFFFFFu);
}

TEST(PoseFrames, ClassicRoundTrip) {
  const auto p = sample_pose();
  std::uint8_t xy[8], attr[8];
  ipc::encode_pose_xy(p, xy);
  ipc::encode_pose_attr(p, attr);
  ipc::PoseXy dxy;
  ipc::PoseAttr da;
  ASSERT_TRUE(ipc::decode_pose_xy(xy, 8, dxy));
  ASSERT_TRUE(ipc::decode_pose_attr(attr, 8, da));
  EXPECT_EQ(dxy.x_nm, 12345);
  EXPECT_EQ(dxy.y_nm, -6790);
  EXPECT_EQ(dxy.seq, 0x34);
  EXPECT_EQ(da.seq, dxy.seq);  // both frames of one pose carry the same counter
  EXPECT_EQ(da.phi_mdeg, -37123);
  EXPECT_EQ(da.score_milli, 877);
  EXPECT_EQ(da.state, ipc::WireState::kTracking);
  EXPECT_EQ(da.age_us, 2344) << "2345.678 µs to the nearest 8 µs step";
  EXPECT_EQ(da.angle_order, 1);
  EXPECT_FALSE(da.look_alike);
  auto q = p;
  q.look_alike = true;
  q.age_ns = 1'000'000'000;  // saturating age must not spill into the flag, nor the flag into the age
  ipc::encode_pose_attr(q, attr);
  ASSERT_TRUE(ipc::decode_pose_attr(attr, 8, da));
  EXPECT_TRUE(da.look_alike);
  EXPECT_EQ(da.age_us, 32760);
  EXPECT_EQ(da.angle_order, 1);
  EXPECT_EQ(da.seq, 0x34);
  EXPECT_FALSE(ipc::decode_pose_xy(xy, 7, dxy)) << "wrong DLC must be refused";
}

TEST(PoseFrames, FdRoundTrip) {
  auto p = sample_pose();
  p.state = ipc::WireState::kLost;
  p.reason_bits = 0xC1;  // bit 7 (unexplained) too
  p.target_scale = 0.87654;
  p.sigma_x_nm = 3.217;
  p.sigma_y_nm = 12.5;
  p.sigma_phi_deg = 0.123456;
  p.sigma_scale = 0.001234;
  std::uint8_t d[64];
  ipc::encode_pose_fd(p, d);
  ipc::PoseFd f;
  ASSERT_TRUE(ipc::decode_pose_fd(d, 64, f));
  EXPECT_EQ(f.x_nm, 12345);
  EXPECT_EQ(f.y_nm, -6790);
  EXPECT_EQ(f.phi_mdeg, -37123);
  EXPECT_EQ(f.score_e4, 8765);
  EXPECT_EQ(f.state, ipc::WireState::kLost);
  EXPECT_EQ(f.reason_bits, 0xC1);
  EXPECT_EQ(f.seq, 0x1234u);
  EXPECT_EQ(f.age_us, 2345u);
  EXPECT_EQ(f.psr_centi, 1234);
  EXPECT_EQ(f.pattern_set, 3);
  EXPECT_EQ(f.target, 2);
  EXPECT_EQ(f.dwell_ns, 250u);
  EXPECT_EQ(f.frame_seq, 0x42u);
  EXPECT_EQ(f.scale_pm_per_px, 39500u);
  EXPECT_EQ(f.target_scale_e4, 8765u);
  EXPECT_EQ(f.sigma_x_pm, 3217u);
  EXPECT_EQ(f.sigma_y_pm, 12500u);
  EXPECT_EQ(f.sigma_phi_udeg, 123456u);
  EXPECT_EQ(f.sigma_scale_e6, 1234u);
  EXPECT_FALSE(f.look_alike);
  EXPECT_EQ(f.angle_order, 1);
  EXPECT_EQ(d[58], 0);
  EXPECT_EQ(d[59], 1) << "angle_order is byte 59";
  for (int i = 60; i < 64; ++i) EXPECT_EQ(d[i], 0) << "reserved byte " << i;
  p.look_alike = true;
  ipc::encode_pose_fd(p, d);
  ASSERT_TRUE(ipc::decode_pose_fd(d, 64, f));
  EXPECT_TRUE(f.look_alike);
  EXPECT_EQ(f.sigma_scale_e6, 1234u);
  EXPECT_EQ(d[58], 1) << "look_alike is bit 464, the lowest of byte 58";
  for (int i = 60; i < 64; ++i) EXPECT_EQ(d[i], 0) << "reserved byte " << i;
}

// A symmetric target's angle is known modulo 360°/n only: every pose says n, in POSE_ATTR next to
// the angle (bits 60-62, where the age's top bits were: the age keeps its 32.76 ms range in 8 µs
// steps) and in POSE_FD (byte 59); neither the saturated age nor look_alike spills into it.
TEST(PoseFrames, AngleOrderTravelsWithThePose) {
  auto p = sample_pose();
  p.age_ns = 1'000'000'000;
  p.look_alike = true;
  for (std::uint8_t order : {1, 2, 3, 4, 6, 7}) {
    p.angle_order = order;
    const auto [da, f] = through_attr_and_fd(p);
    EXPECT_EQ(da.angle_order, order);
    EXPECT_EQ(f.angle_order, order);
    EXPECT_EQ(da.age_us, 32760) << "order " << int(order);
    EXPECT_TRUE(da.look_alike);
    EXPECT_TRUE(f.look_alike);
    EXPECT_EQ(da.phi_mdeg, -37123);
    EXPECT_EQ(f.age_us, 1'000'000u);
  }
  // An order the field cannot hold is "not said" (0), never a smaller one claiming more.
  for (std::uint8_t order : {0, 8, 12, 255}) {
    p.angle_order = order;
    const auto [da, f] = through_attr_and_fd(p);
    EXPECT_EQ(da.angle_order, 0) << int(order);
    EXPECT_EQ(f.angle_order, 0) << int(order);
    EXPECT_TRUE(da.look_alike);
  }
  // The age to the nearest 8 µs step, 0 at and below zero.
  p.angle_order = 2;
  for (auto [ns, us] : {std::pair<std::int64_t, int>{0, 0}, {3'999, 0}, {4'000, 8}, {11'999, 8}, {12'000, 16}, {32'763'999, 32760}}) {
    p.age_ns = ns;
    const ipc::PoseAttr da = through_attr_and_fd(p).first;
    EXPECT_EQ(da.age_us, us) << ns << " ns";
    EXPECT_EQ(da.angle_order, 2);
  }
}

TEST(PoseFrames, UncertaintyRoundTripAndSaturation) {
  auto p = sample_pose();
  p.target_scale = 1.2345;
  p.sigma_x_nm = 4.26;
  p.sigma_y_nm = 0.04;  // below the 0.1 nm step: 0 on the wire ("not measured" or tiny)
  p.sigma_phi_deg = 0.3456;
  p.sigma_scale = 0.0123;
  std::uint8_t d[8];
  ipc::encode_pose_unc(p, d);
  ipc::PoseUnc u;
  ASSERT_TRUE(ipc::decode_pose_unc(d, 8, u));
  EXPECT_EQ(u.sigma_x_dnm, 43);
  EXPECT_EQ(u.sigma_y_dnm, 0);
  EXPECT_EQ(u.sigma_phi_mdeg, 346);
  EXPECT_EQ(u.target_scale_e4, 7345);
  EXPECT_EQ(u.sigma_scale, 25);  // 0.0123 / 0.0005 = 24.6
  EXPECT_EQ(u.seq, 0x34);        // the same counter as POSE_XY and POSE_ATTR
  EXPECT_FALSE(ipc::decode_pose_unc(d, 7, u)) << "wrong DLC must be refused";
  // Saturation at the field's ends; NaN and negative σ are 0.
  p.sigma_x_nm = 1e9;
  p.sigma_y_nm = -3;
  p.sigma_phi_deg = std::nan("");
  p.target_scale = 0.1;
  p.sigma_scale = 5;
  ipc::encode_pose_unc(p, d);
  ASSERT_TRUE(ipc::decode_pose_unc(d, 8, u));
  EXPECT_EQ(u.sigma_x_dnm, 4095);
  EXPECT_EQ(u.sigma_y_dnm, 0);
  EXPECT_EQ(u.sigma_phi_mdeg, 0);
  EXPECT_EQ(u.target_scale_e4, 0);
  EXPECT_EQ(u.sigma_scale, 127);
}

TEST(PoseFrames, SaturatesOutOfRangeValues) {
  auto p = sample_pose();
  p.x_nm = 1e12;
  p.y_nm = -1e12;
  p.score = 7.0;
  p.age_ns = std::numeric_limits<std::int64_t>::max();
  std::uint8_t xy[8], attr[8];
  ipc::encode_pose_xy(p, xy);
  ipc::encode_pose_attr(p, attr);
  ipc::PoseXy dxy;
  ipc::PoseAttr da;
  ipc::decode_pose_xy(xy, 8, dxy);
  ipc::decode_pose_attr(attr, 8, da);
  EXPECT_EQ(dxy.x_nm, ipc::signed_max(ipc::kXyBits));
  EXPECT_EQ(dxy.y_nm, ipc::signed_min(ipc::kXyBits));
  EXPECT_EQ(da.score_milli, 1000);
  EXPECT_EQ(da.age_us, 32760);
  EXPECT_FALSE(da.look_alike);
  p.score = -3;
  p.age_ns = -5;  // clock step: never a huge unsigned age
  ipc::encode_pose_attr(p, attr);
  ipc::decode_pose_attr(attr, 8, da);
  EXPECT_EQ(da.score_milli, -1000);
  EXPECT_EQ(da.age_us, 0);
}

TEST(PoseFrames, NanAndInfinityBecomeDefinedValues) {
  auto p = sample_pose();
  p.x_nm = std::nan("");
  p.y_nm = std::numeric_limits<double>::infinity();
  p.phi_deg = std::nan("");
  p.score = std::nan("");
  std::uint8_t xy[8], attr[8];
  ipc::encode_pose_xy(p, xy);
  ipc::encode_pose_attr(p, attr);
  ipc::PoseXy dxy;
  ipc::PoseAttr da;
  ipc::decode_pose_xy(xy, 8, dxy);
  ipc::decode_pose_attr(attr, 8, da);
  EXPECT_EQ(dxy.x_nm, 0);
  EXPECT_EQ(dxy.y_nm, ipc::signed_max(ipc::kXyBits));
  EXPECT_EQ(da.phi_mdeg, 0);
  EXPECT_EQ(da.score_milli, 0);
}

TEST(PoseFrames, AngleWrapsIntoHalfOpenRange) {
  EXPECT_EQ(ipc::phi_to_mdeg(180.0), 180000);
  EXPECT_EQ(ipc::phi_to_mdeg(-180.0), 180000);  // (-180, 180]
  EXPECT_EQ(ipc::phi_to_mdeg(190.0), -170000);
  EXPECT_EQ(ipc::phi_to_mdeg(-190.0), 170000);
  EXPECT_EQ(ipc::phi_to_mdeg(720.5), 500);
  EXPECT_EQ(ipc::phi_to_mdeg(-0.0004), 0);
  EXPECT_EQ(ipc::phi_to_mdeg(-179.9996), 180000);
  for (double phi = -179.999; phi <= 180.0; phi += 7.3) {
    std::uint8_t attr[8];
    auto p = sample_pose();
    p.phi_deg = phi;
    ipc::encode_pose_attr(p, attr);
    ipc::PoseAttr da;
    ipc::decode_pose_attr(attr, 8, da);
    EXPECT_NEAR(da.phi_mdeg / 1000.0, phi, 0.0005);
  }
}

TEST(PoseFrames, NegativeCoordinatesAndCounterWrap) {
  auto p = sample_pose();
  for (std::uint32_t seq : {0u, 1u, 254u, 255u, 256u, 257u, 0xFFFFFFFFu}) {
    p.seq = seq;
    p.x_nm = -1.0 * seq;
    std::uint8_t xy[8], attr[8];
    ipc::encode_pose_xy(p, xy);
    ipc::encode_pose_attr(p, attr);
    ipc::PoseXy dxy;
    ipc::PoseAttr da;
    ipc::decode_pose_xy(xy, 8, dxy);
    ipc::decode_pose_attr(attr, 8, da);
    EXPECT_EQ(dxy.seq, seq & 0xFF);
    EXPECT_EQ(da.seq, seq & 0xFF);
    const std::int64_t expect_x = -static_cast<std::int64_t>(seq);
    EXPECT_EQ(dxy.x_nm, std::max<std::int64_t>(expect_x, ipc::signed_min(ipc::kXyBits)));
  }
  // A receiver computes gaps modulo 256: 255 -> 0 is one step.
  EXPECT_EQ(static_cast<std::uint8_t>(std::uint8_t{0} - std::uint8_t{255}), 1);
}

TEST(Heartbeat, RoundTripAndModularCounters) {
  ipc::Heartbeat h;
  h.state = ipc::WireState::kLost;
  h.running = false;
  h.bus_state = ipc::BusState::kBusOff;
  h.fd = true;
  h.pattern_set = 9;
  h.bad_commands = 0x13;  // mod 16 -> 3
  h.counter = 255;
  h.last_command_seq = 77;
  h.dwell_ns = 65535;
  h.dropped_frames = 200;
  h.overruns = 0x1F;
  h.tx_dropped = 0x25;
  std::uint8_t d[8];
  ipc::encode_heartbeat(h, d);
  ipc::Heartbeat o;
  ASSERT_TRUE(ipc::decode_heartbeat(d, 8, o));
  EXPECT_EQ(o.state, ipc::WireState::kLost);
  EXPECT_FALSE(o.running);
  EXPECT_EQ(o.bus_state, ipc::BusState::kBusOff);
  EXPECT_TRUE(o.fd);
  EXPECT_EQ(o.pattern_set, 9);
  EXPECT_EQ(o.bad_commands, 3);
  EXPECT_EQ(o.counter, 255);
  EXPECT_EQ(o.last_command_seq, 77);
  EXPECT_EQ(o.dwell_ns, 65535);
  EXPECT_EQ(o.dropped_frames, 200);
  EXPECT_EQ(o.overruns, 0xF);
  EXPECT_EQ(o.tx_dropped, 0x5);
  h.pattern_set = 40;  // out of the 4-bit field: saturates, never aliases to another set
  ipc::encode_heartbeat(h, d);
  ipc::decode_heartbeat(d, 8, o);
  EXPECT_EQ(o.pattern_set, 15);
}

TEST(Commands, ValidOnesRoundTrip) {
  const ipc::WireCommand cmds[] = {
      {ipc::Opcode::kSelectPatternSet, 1, 15, 39500},
      {ipc::Opcode::kSelectPatternSet, 2, 0, 0},
      {ipc::Opcode::kStart, 255, 0, 0},
      {ipc::Opcode::kStop, 0, 0, 0},
      {ipc::Opcode::kReacquire, 9, 3, 0},
      {ipc::Opcode::kReacquire, 10, ipc::kAllTargets, 0},
  };
  for (const auto& c : cmds) {
    std::uint8_t d[8];
    ipc::encode_command(c, d);
    ipc::WireCommand o;
    ASSERT_EQ(ipc::decode_command(d, 8, o), ipc::CommandCheck::kOk);
    EXPECT_EQ(o, c);
  }
}

TEST(Commands, InvalidOnesAreRejectedWithAReason) {
  auto check = [](std::initializer_list<std::uint8_t> bytes, std::uint8_t len = 8) {
    std::uint8_t d[8]{};
    int i = 0;
    for (auto b : bytes) d[i++] = b;
    ipc::WireCommand o;
    return ipc::decode_command(d, len, o);
  };
  EXPECT_EQ(check({2, 1}, 7), ipc::CommandCheck::kBadLength);
  EXPECT_EQ(check({2, 1}, 0), ipc::CommandCheck::kBadLength);
  EXPECT_EQ(check({0, 1}), ipc::CommandCheck::kUnknownOpcode);
  EXPECT_EQ(check({5, 1}), ipc::CommandCheck::kUnknownOpcode);
  EXPECT_EQ(check({0xFF, 1}), ipc::CommandCheck::kUnknownOpcode);
  EXPECT_EQ(check({1, 1, 16}), ipc::CommandCheck::kBadArgument);       // pattern set 16
  EXPECT_EQ(check({4, 1, 4}), ipc::CommandCheck::kBadArgument);        // target 4
  EXPECT_EQ(check({2, 1, 1}), ipc::CommandCheck::kBadArgument);        // start with an arg
  EXPECT_EQ(check({3, 1, 0, 1}), ipc::CommandCheck::kReservedNotZero);
  EXPECT_EQ(check({3, 1, 0, 0, 1}), ipc::CommandCheck::kBadScale);     // scale on stop
  // 100 µm/px + 1 pm: above the limit.
  EXPECT_EQ(check({1, 1, 0, 0, 0x01, 0xE1, 0xF5, 0x05}), ipc::CommandCheck::kBadScale);
  EXPECT_EQ(check({1, 1, 0, 0, 0x00, 0xE1, 0xF5, 0x05}), ipc::CommandCheck::kOk);
}

TEST(IdMap, BlocksAndCollisions) {
  const auto ids = ipc::IdMap::with_base(0x100);
  EXPECT_TRUE(ids.valid());
  EXPECT_EQ(ids.pose_xy(0), 0x100u);
  EXPECT_EQ(ids.pose_attr(3), 0x131u);
  EXPECT_EQ(ids.pose_fd(1), 0x112u);
  EXPECT_EQ(ids.heartbeat(), 0x140u);
  EXPECT_EQ(ids.command, 0x150u);
  EXPECT_EQ(ids.classify(0x121).kind, ipc::MessageKind::kPoseAttr);
  EXPECT_EQ(ids.classify(0x121).target, 2);
  EXPECT_EQ(ids.classify(0x150).kind, ipc::MessageKind::kCommand);
  EXPECT_EQ(ids.classify(0x103).kind, ipc::MessageKind::kPoseUnc);
  EXPECT_EQ(ids.pose_unc(2), 0x123u);
  EXPECT_EQ(ids.classify(0x104).kind, ipc::MessageKind::kUnknown);
  EXPECT_FALSE((ipc::IdMap{0x100, 0x111}.valid())) << "command id on a pose id";
  EXPECT_FALSE((ipc::IdMap{0x100, 0x140}.valid())) << "command id on the heartbeat";
  EXPECT_FALSE(ipc::IdMap::with_base(0x7F0).valid()) << "heartbeat above 0x7FF";
  EXPECT_TRUE((ipc::IdMap{0x100, 0x050}.valid()));
}

TEST(Codec, EncodeAndDecodeDoNotAllocate) {
  auto p = sample_pose();
  std::uint8_t d8[8], d64[64];
  ipc::PoseXy xy;
  ipc::PoseAttr at;
  ipc::PoseFd fd;
  ipc::Heartbeat h;
  ipc::WireCommand c;
  std::uint64_t sum = 0;
  {
    sempose::rt::alloc::ScopedArm arm;
    for (int i = 0; i < 1000; ++i) {
      p.seq = static_cast<std::uint32_t>(i);
      p.x_nm = i * 1.5 - 700;
      ipc::encode_pose_xy(p, d8);
      ipc::decode_pose_xy(d8, 8, xy);
      ipc::encode_pose_attr(p, d8);
      ipc::decode_pose_attr(d8, 8, at);
      ipc::encode_pose_fd(p, d64);
      ipc::decode_pose_fd(d64, 64, fd);
      ipc::encode_heartbeat(h, d8);
      ipc::decode_heartbeat(d8, 8, h);
      ipc::decode_command(d8, 8, c);
      sum += static_cast<std::uint64_t>(xy.x_nm + at.seq + fd.seq);
    }
    EXPECT_EQ(sempose::rt::alloc::this_thread_allocations(), 0u);
  }
  EXPECT_NE(sum, 0u);
}

// All eight reason bits survive the classic ATTR frame (bit 7, unexplained, sits in bit 39,
// unused before; the seq byte next to it is untouched).
TEST(PoseFrames, ClassicAttrCarriesAllReasonBits) {
  auto p = sample_pose();
  p.reason_bits = 0x80;
  std::uint8_t attr[8];
  ipc::encode_pose_attr(p, attr);
  ipc::PoseAttr da;
  ASSERT_TRUE(ipc::decode_pose_attr(attr, 8, da));
  EXPECT_EQ(da.reason_bits, 0x80);
  EXPECT_EQ(da.seq, p.seq & 0xFFu);
}
