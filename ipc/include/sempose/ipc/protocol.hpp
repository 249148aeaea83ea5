// The sempose CAN wire protocol (ipc/sempose.dbc describes the same frames for standard tools).
//
// Classic CAN 2.0, 8-byte frames, standard 11-bit ids from a configurable base (default 0x100):
//   base + 0x10*t + 0   POSE_XY    x_nm, y_nm (signed 28 bit each, saturating), seq
//   base + 0x10*t + 1   POSE_ATTR  phi (mdeg), score (1/1000), state, reason bits, seq, age (8 µs),
//                                  angle order, look_alike
//   base + 0x10*t + 2   POSE_FD    (CAN FD only, 64 bytes) everything above at full width
//   base + 0x10*t + 3   POSE_UNC   1σ of x, y (0.1 nm), φ (mdeg), scale; the target's scale; seq
//   base + 0x40         HEARTBEAT  state, bus state, pattern set, dwell, counters (fixed rate)
//   base + 0x50         COMMAND    from the controller: select pattern set, start, stop, re-acquire
// t = target index 0..3. All signals little-endian (DBC "@1"). seq is the low 8 bits (32 in FD)
// of the per-target pose counter and is the same in the three classic frames of one pose, so
// a receiver pairs them and sees gaps. A σ of 0 means "not measured" (no match, a frame of the
// start search).
//
// The layout is versioned: kWireVersion below, the DBC's VERSION "sempose-<n>" (tests/ipc checks
// the two agree). Version 2 put the angle's rotational order into POSE_ATTR (age there in 8 µs
// steps to make room) and POSE_FD.
//
// Pure and header-only: encode/decode are noexcept, allocation-free, and depend on nothing
// but the standard library. Out-of-range inputs saturate; NaN becomes 0 (see bit_pack.hpp).
#pragma once

#include <cmath>
#include <cstdint>

#include "sempose/ipc/bit_pack.hpp"

namespace sempose::ipc {

// +1 whenever a frame's layout or a signal's meaning changes (and the DBC's VERSION with it).
inline constexpr int kWireVersion = 2;

inline constexpr std::uint8_t kClassicLen = 8;
inline constexpr std::uint8_t kFdLen = 64;
inline constexpr std::uint32_t kDefaultBaseId = 0x100;
inline constexpr std::uint32_t kTargetBlock = 0x10;
inline constexpr int kMaxTargets = 4;
inline constexpr std::uint32_t kPoseXyOffset = 0;
inline constexpr std::uint32_t kPoseAttrOffset = 1;
inline constexpr std::uint32_t kPoseFdOffset = 2;
inline constexpr std::uint32_t kPoseUncOffset = 3;
inline constexpr std::uint32_t kHeartbeatOffset = 0x40;
inline constexpr std::uint32_t kCommandOffset = 0x50;
inline constexpr std::uint32_t kMaxStandardId = 0x7FF;
inline constexpr int kMaxPatternSets = 16;  // 4-bit field in the heartbeat

// ---- field widths (must match ipc/sempose.dbc; tests/ipc checks them against it) ----
inline constexpr unsigned kXyBits = 28;        // ±134 217 727 nm = ±134 mm
// The largest |x|, |y| POSE_XY carries (1 nm steps); a position beyond it saturates.
inline constexpr double kXyMaxNm = static_cast<double>((std::int64_t{1} << (kXyBits - 1)) - 1);
inline constexpr unsigned kPhiBits = 19;       // ±262 143 mdeg holds ±180 000
inline constexpr unsigned kScoreBits = 11;     // ±1023 holds ±1000 (score × 1000)
inline constexpr unsigned kAgeBits = 12;       // × 8 µs: 0..32 760 µs (bits 60-62 angle order, 63 look_alike)
inline constexpr std::int64_t kAgeStepNs = 8'000;
inline constexpr unsigned kAngleOrderBits = 3;  // 1..7 (pattern orders are 1, 2, 3, 4, 6); 0 = not said
inline constexpr std::int64_t kPhiMaxMdeg = 180'000;
inline constexpr std::int64_t kScoreMaxMilli = 1'000;
// POSE_UNC (classic): σx, σy in 0.1 nm (12 bit: ≤ 409.5 nm), σφ in mdeg (11 bit: ≤ 2.047°),
// target scale − 0.5 in 1/10 000 (14 bit: 0.5 … 2.1383), σ of the scale in 1/2000 (7 bit:
// ≤ 0.0635). All saturate; the FD frame carries the same at full width.
inline constexpr unsigned kSigmaXyBits = 12;
inline constexpr unsigned kSigmaPhiBits = 11;
inline constexpr unsigned kUncScaleBits = 14;
inline constexpr double kUncScaleOffset = 0.5;
inline constexpr unsigned kSigmaScaleBits = 7;
inline constexpr double kSigmaScaleStep = 0.0005;

// Wire values of the tracker state (the same numbers as pose::TrackState).
enum class WireState : std::uint8_t { kTracking = 0, kAcquiring = 1, kLost = 2, kUncertain = 3 };
enum class BusState : std::uint8_t { kActive = 0, kPassive = 1, kBusOff = 2 };

enum class Opcode : std::uint8_t {
  kSelectPatternSet = 1,  // arg = pattern set 0..15; scale_pm_per_px = its nm/px × 1000 (0 = keep)
  kStart = 2,
  kStop = 3,
  kReacquire = 4,         // arg = target 0..3, or 0xFF = all
};
inline constexpr std::uint8_t kAllTargets = 0xFF;
inline constexpr std::uint32_t kMaxScalePmPerPx = 100'000'000;  // 100 µm per pixel

// Which message an id is, for a given base.
enum class MessageKind : std::uint8_t { kUnknown = 0, kPoseXy, kPoseAttr, kPoseFd, kHeartbeat, kCommand, kPoseUnc };

struct IdMap {
  std::uint32_t base = kDefaultBaseId;
  std::uint32_t command = kDefaultBaseId + kCommandOffset;

  static constexpr IdMap with_base(std::uint32_t b) noexcept { return {b, b + kCommandOffset}; }
  constexpr std::uint32_t pose_xy(int target) const noexcept { return base + kTargetBlock * static_cast<std::uint32_t>(target) + kPoseXyOffset; }
  constexpr std::uint32_t pose_attr(int target) const noexcept { return base + kTargetBlock * static_cast<std::uint32_t>(target) + kPoseAttrOffset; }
  constexpr std::uint32_t pose_fd(int target) const noexcept { return base + kTargetBlock * static_cast<std::uint32_t>(target) + kPoseFdOffset; }
  constexpr std::uint32_t pose_unc(int target) const noexcept { return base + kTargetBlock * static_cast<std::uint32_t>(target) + kPoseUncOffset; }
  constexpr std::uint32_t heartbeat() const noexcept { return base + kHeartbeatOffset; }
  // Every id fits 11 bits and the command id does not collide with a sempose-sent id.
  constexpr bool valid() const noexcept {
    if (heartbeat() > kMaxStandardId || command > kMaxStandardId) return false;
    return classify_sent(command).kind == MessageKind::kUnknown;
  }
  struct Classified { MessageKind kind = MessageKind::kUnknown; int target = -1; };
  constexpr Classified classify_sent(std::uint32_t id) const noexcept {
    if (id == heartbeat()) return {MessageKind::kHeartbeat, -1};
    if (id < base || id >= base + kTargetBlock * kMaxTargets) return {};
    const auto rel = id - base;
    const int t = static_cast<int>(rel / kTargetBlock);
    switch (rel % kTargetBlock) {
      case kPoseXyOffset: return {MessageKind::kPoseXy, t};
      case kPoseAttrOffset: return {MessageKind::kPoseAttr, t};
      case kPoseFdOffset: return {MessageKind::kPoseFd, t};
      case kPoseUncOffset: return {MessageKind::kPoseUnc, t};
      default: return {};
    }
  }
  constexpr Classified classify(std::uint32_t id) const noexcept {
    if (id == command) return {MessageKind::kCommand, -1};
    return classify_sent(id);
  }
};

// ---- physical values in, wire integers out ----

// One pose in physical units (what the encoder is given).
struct PoseValues {
  double x_nm = 0;
  double y_nm = 0;
  double phi_deg = 0;
  double score = 0;
  double psr = 0;
  WireState state = WireState::kAcquiring;
  std::uint8_t reason_bits = 0;  // pose::LostReason bits (all 8 used)
  // A target with the same pattern is on this pose's place (UNCERTAIN while both are there),
  // or this pose comes from the search sempose started because of it (its reason 32, on an
  // ACQUIRING frame, is then sempose's own, not a REACQUIRE).
  bool look_alike = false;
  // The angle is known modulo 360°/angle_order (pose::PoseEstimate::angle_order: a target that
  // looks the same turned by that much); 1 = a full turn. Outside 1..7 goes out as 0, "not said".
  std::uint8_t angle_order = 1;
  std::uint32_t seq = 0;
  std::int64_t age_ns = 0;       // beam on the target -> send
  std::uint8_t pattern_set = 0;
  std::uint8_t target = 0;
  std::uint32_t dwell_ns = 0;
  std::uint64_t frame_seq = 0;
  double nm_per_px = 0;
  double target_scale = 0;     // the target's size over its pattern's (FD and POSE_UNC)
  // 1σ of the measured pose (0 = not measured): nm at nm_per_px, degrees, scale.
  double sigma_x_nm = 0, sigma_y_nm = 0, sigma_phi_deg = 0, sigma_scale = 0;
};

// Wraps into (-180, 180] then rounds to millidegrees.
inline std::int32_t phi_to_mdeg(double phi_deg) noexcept {
  if (!std::isfinite(phi_deg)) return 0;
  double w = std::remainder(phi_deg, 360.0);  // [-180, 180]
  if (w <= -180.0) w += 360.0;
  const auto mdeg = saturate_round(w * 1000.0, -kPhiMaxMdeg, kPhiMaxMdeg);
  // -179.9996° rounds to -180.000°, which the half-open range (-180, 180] writes as +180.000°.
  return static_cast<std::int32_t>(mdeg == -kPhiMaxMdeg ? kPhiMaxMdeg : mdeg);
}
inline std::int32_t nm_to_wire(double nm, unsigned bits) noexcept {
  return static_cast<std::int32_t>(saturate_round(nm, signed_min(bits), signed_max(bits)));
}
inline std::int16_t score_to_milli(double score) noexcept {
  return static_cast<std::int16_t>(saturate_round(score * 1000.0, -kScoreMaxMilli, kScoreMaxMilli));
}
inline std::uint32_t age_to_us(std::int64_t age_ns, unsigned bits) noexcept {
  if (age_ns <= 0) return 0;
  const std::int64_t us = age_ns / 1000;
  return static_cast<std::uint32_t>(clamp_i64(us, 0, static_cast<std::int64_t>(unsigned_max(bits))));
}
// POSE_ATTR's age: in kAgeStepNs steps, rounded to the nearest (≤ 4 µs off), saturating.
inline std::uint32_t age_to_steps(std::int64_t age_ns) noexcept {
  if (age_ns <= 0) return 0;
  const std::int64_t steps = age_ns / kAgeStepNs + (age_ns % kAgeStepNs >= kAgeStepNs / 2 ? 1 : 0);
  return static_cast<std::uint32_t>(clamp_i64(steps, 0, static_cast<std::int64_t>(unsigned_max(kAgeBits))));
}
// An order the field cannot hold is "not said" (0), never a smaller order that would claim more.
inline std::uint8_t angle_order_to_wire(std::uint8_t order) noexcept {
  return order >= 1 && order <= unsigned_max(kAngleOrderBits) ? order : 0;
}

// ---- decoded frames (wire integers) ----

struct PoseXy {
  std::int32_t x_nm = 0;
  std::int32_t y_nm = 0;
  std::uint8_t seq = 0;
  friend bool operator==(const PoseXy&, const PoseXy&) = default;
};

struct PoseAttr {
  std::int32_t phi_mdeg = 0;
  std::int16_t score_milli = 0;
  WireState state = WireState::kAcquiring;
  std::uint8_t reason_bits = 0;
  std::uint8_t seq = 0;
  std::uint16_t age_us = 0;        // a multiple of 8 (the wire's step)
  std::uint8_t angle_order = 0;    // 1..7; 0 = not said
  bool look_alike = false;
  friend bool operator==(const PoseAttr&, const PoseAttr&) = default;
};

struct PoseFd {
  std::int32_t x_nm = 0;
  std::int32_t y_nm = 0;
  std::int32_t phi_mdeg = 0;
  std::int16_t score_e4 = 0;      // score × 10 000
  WireState state = WireState::kAcquiring;
  std::uint8_t reason_bits = 0;
  std::uint32_t seq = 0;
  std::uint32_t age_us = 0;
  std::uint16_t psr_centi = 0;    // psr × 100
  std::uint8_t pattern_set = 0;
  std::uint8_t target = 0;
  std::uint32_t dwell_ns = 0;
  std::uint32_t frame_seq = 0;    // low 32 bits
  std::uint32_t scale_pm_per_px = 0;
  std::uint16_t target_scale_e4 = 0;  // the target's size over its pattern's × 10 000
  std::uint32_t sigma_x_pm = 0, sigma_y_pm = 0;  // 1σ, picometres
  std::uint32_t sigma_phi_udeg = 0;              // 1σ, µdeg
  std::uint32_t sigma_scale_e6 = 0;              // 1σ of the target's scale × 10⁶
  bool look_alike = false;
  std::uint8_t angle_order = 0;    // 1..7; 0 = not said
  friend bool operator==(const PoseFd&, const PoseFd&) = default;
};

struct PoseUnc {
  std::uint16_t sigma_x_dnm = 0;     // 0.1 nm
  std::uint16_t sigma_y_dnm = 0;
  std::uint16_t sigma_phi_mdeg = 0;
  std::uint16_t target_scale_e4 = 0; // (scale − 0.5) × 10 000
  std::uint8_t sigma_scale = 0;      // × 2000
  std::uint8_t seq = 0;
  friend bool operator==(const PoseUnc&, const PoseUnc&) = default;
};

struct Heartbeat {
  WireState state = WireState::kAcquiring;
  bool running = true;
  BusState bus_state = BusState::kActive;
  bool fd = false;                  // poses go out as CAN FD frames
  bool output_fault = false;        // a file output (CSV, candump log) failed to write
  bool stalled = false;             // the scan source or an RT stage made no progress for too long
  std::uint8_t pattern_set = 0;     // 0..15
  std::uint8_t bad_commands = 0;    // mod 16
  std::uint8_t counter = 0;         // +1 per heartbeat, wraps
  std::uint8_t last_command_seq = 0;// seq of the last accepted command (echo)
  std::uint16_t dwell_ns = 0;       // saturating
  std::uint8_t dropped_frames = 0;  // mod 256
  std::uint8_t overruns = 0;        // mod 16
  std::uint8_t tx_dropped = 0;      // CAN frames sempose could not send, mod 16
  friend bool operator==(const Heartbeat&, const Heartbeat&) = default;
};

struct WireCommand {
  Opcode opcode = Opcode::kStart;
  std::uint8_t seq = 0;
  std::uint8_t arg = 0;
  std::uint32_t scale_pm_per_px = 0;
  friend bool operator==(const WireCommand&, const WireCommand&) = default;
};

enum class CommandCheck : std::uint8_t {
  kOk = 0,
  kBadLength,       // DLC != 8
  kUnknownOpcode,
  kBadArgument,     // pattern set > 15, target > 3 (and != 0xFF), or arg on start/stop
  kReservedNotZero, // byte 3 must be 0
  kBadScale,        // scale > 100 µm/px, or a scale on anything but select
};

constexpr const char* to_string(CommandCheck c) noexcept {
  switch (c) {
    case CommandCheck::kOk: return "ok";
    case CommandCheck::kBadLength: return "bad length";
    case CommandCheck::kUnknownOpcode: return "unknown opcode";
    case CommandCheck::kBadArgument: return "bad argument";
    case CommandCheck::kReservedNotZero: return "reserved byte not zero";
    case CommandCheck::kBadScale: return "bad scale";
  }
  return "?";
}

// ---- encoders: data must hold kClassicLen (or kFdLen) bytes; every byte is written ----

// A non-negative physical value × factor, rounded, saturating to [0, 2^bits − 1] (NaN → 0).
inline std::uint64_t unsigned_wire(double v, double factor, unsigned bits) noexcept {
  return static_cast<std::uint64_t>(saturate_round(v * factor, 0, static_cast<std::int64_t>(unsigned_max(bits))));
}

inline void encode_pose_xy(const PoseValues& p, std::uint8_t* data) noexcept {
  for (int i = 0; i < kClassicLen; ++i) data[i] = 0;
  put_bits(data, 0, kXyBits, static_cast<std::uint64_t>(nm_to_wire(p.x_nm, kXyBits)));
  put_bits(data, 28, kXyBits, static_cast<std::uint64_t>(nm_to_wire(p.y_nm, kXyBits)));
  put_bits(data, 56, 8, p.seq & 0xFFu);
}

inline void encode_pose_attr(const PoseValues& p, std::uint8_t* data) noexcept {
  for (int i = 0; i < kClassicLen; ++i) data[i] = 0;
  put_bits(data, 0, kPhiBits, static_cast<std::uint64_t>(static_cast<std::int64_t>(phi_to_mdeg(p.phi_deg))));
  put_bits(data, 19, kScoreBits, static_cast<std::uint64_t>(static_cast<std::int64_t>(score_to_milli(p.score))));
  put_bits(data, 30, 2, static_cast<std::uint8_t>(p.state) & 0x3u);
  put_bits(data, 32, 8, p.reason_bits);
  put_bits(data, 40, 8, p.seq & 0xFFu);
  put_bits(data, 48, kAgeBits, age_to_steps(p.age_ns));
  put_bits(data, 60, kAngleOrderBits, angle_order_to_wire(p.angle_order));
  put_bits(data, 63, 1, p.look_alike ? 1u : 0u);
}

inline void encode_pose_fd(const PoseValues& p, std::uint8_t* data) noexcept {
  for (int i = 0; i < kFdLen; ++i) data[i] = 0;
  put_bits(data, 0, 32, static_cast<std::uint64_t>(static_cast<std::int64_t>(nm_to_wire(p.x_nm, 32))));
  put_bits(data, 32, 32, static_cast<std::uint64_t>(static_cast<std::int64_t>(nm_to_wire(p.y_nm, 32))));
  put_bits(data, 64, 32, static_cast<std::uint64_t>(static_cast<std::int64_t>(phi_to_mdeg(p.phi_deg))));
  put_bits(data, 96, 16, static_cast<std::uint64_t>(saturate_round(p.score * 10000.0, -10000, 10000)));
  put_bits(data, 112, 8, static_cast<std::uint8_t>(p.state));
  put_bits(data, 120, 8, p.reason_bits);
  put_bits(data, 128, 32, p.seq);
  put_bits(data, 160, 32, age_to_us(p.age_ns, 32));
  put_bits(data, 192, 16, static_cast<std::uint64_t>(saturate_round(p.psr * 100.0, 0, 65535)));
  put_bits(data, 208, 8, p.pattern_set);
  put_bits(data, 216, 8, p.target);
  put_bits(data, 224, 32, p.dwell_ns);
  put_bits(data, 256, 32, p.frame_seq & 0xFFFFFFFFu);
  put_bits(data, 288, 32, static_cast<std::uint64_t>(saturate_round(p.nm_per_px * 1000.0, 0, 0xFFFFFFFFll)));
  put_bits(data, 320, 16, static_cast<std::uint64_t>(saturate_round(p.target_scale * 10000.0, 0, 65535)));
  put_bits(data, 336, 32, unsigned_wire(p.sigma_x_nm, 1000.0, 32));
  put_bits(data, 368, 32, unsigned_wire(p.sigma_y_nm, 1000.0, 32));
  put_bits(data, 400, 32, unsigned_wire(p.sigma_phi_deg, 1e6, 32));
  put_bits(data, 432, 32, unsigned_wire(p.sigma_scale, 1e6, 32));
  put_bits(data, 464, 1, p.look_alike ? 1u : 0u);
  put_bits(data, 472, 8, angle_order_to_wire(p.angle_order));
}

inline void encode_pose_unc(const PoseValues& p, std::uint8_t* data) noexcept {
  for (int i = 0; i < kClassicLen; ++i) data[i] = 0;
  put_bits(data, 0, kSigmaXyBits, unsigned_wire(p.sigma_x_nm, 10.0, kSigmaXyBits));
  put_bits(data, 12, kSigmaXyBits, unsigned_wire(p.sigma_y_nm, 10.0, kSigmaXyBits));
  put_bits(data, 24, kSigmaPhiBits, unsigned_wire(p.sigma_phi_deg, 1000.0, kSigmaPhiBits));
  put_bits(data, 35, kUncScaleBits, unsigned_wire(p.target_scale - kUncScaleOffset, 10000.0, kUncScaleBits));
  put_bits(data, 49, kSigmaScaleBits, unsigned_wire(p.sigma_scale, 1.0 / kSigmaScaleStep, kSigmaScaleBits));
  put_bits(data, 56, 8, p.seq & 0xFFu);
}

inline void encode_heartbeat(const Heartbeat& h, std::uint8_t* data) noexcept {
  for (int i = 0; i < kClassicLen; ++i) data[i] = 0;
  put_bits(data, 0, 2, static_cast<std::uint8_t>(h.state));
  put_bits(data, 2, 1, h.running ? 1u : 0u);
  put_bits(data, 3, 2, static_cast<std::uint8_t>(h.bus_state));
  put_bits(data, 5, 1, h.fd ? 1u : 0u);
  put_bits(data, 6, 1, h.output_fault ? 1u : 0u);
  put_bits(data, 7, 1, h.stalled ? 1u : 0u);
  put_bits(data, 8, 4, h.pattern_set > 15 ? 15u : h.pattern_set);
  put_bits(data, 12, 4, h.bad_commands & 0xFu);
  put_bits(data, 16, 8, h.counter);
  put_bits(data, 24, 8, h.last_command_seq);
  put_bits(data, 32, 16, h.dwell_ns);
  put_bits(data, 48, 8, h.dropped_frames);
  put_bits(data, 56, 4, h.overruns & 0xFu);
  put_bits(data, 60, 4, h.tx_dropped & 0xFu);
}

inline void encode_command(const WireCommand& c, std::uint8_t* data) noexcept {
  for (int i = 0; i < kClassicLen; ++i) data[i] = 0;
  put_bits(data, 0, 8, static_cast<std::uint8_t>(c.opcode));
  put_bits(data, 8, 8, c.seq);
  put_bits(data, 16, 8, c.arg);
  put_bits(data, 32, 32, c.scale_pm_per_px);
}

// ---- decoders (len is the frame's DLC in bytes) ----

inline bool decode_pose_xy(const std::uint8_t* data, std::uint8_t len, PoseXy& out) noexcept {
  if (len != kClassicLen) return false;
  out.x_nm = static_cast<std::int32_t>(get_signed_bits(data, 0, kXyBits));
  out.y_nm = static_cast<std::int32_t>(get_signed_bits(data, 28, kXyBits));
  out.seq = static_cast<std::uint8_t>(get_bits(data, 56, 8));
  return true;
}

inline bool decode_pose_attr(const std::uint8_t* data, std::uint8_t len, PoseAttr& out) noexcept {
  if (len != kClassicLen) return false;
  out.phi_mdeg = static_cast<std::int32_t>(get_signed_bits(data, 0, kPhiBits));
  out.score_milli = static_cast<std::int16_t>(get_signed_bits(data, 19, kScoreBits));
  out.state = static_cast<WireState>(get_bits(data, 30, 2));
  out.reason_bits = static_cast<std::uint8_t>(get_bits(data, 32, 8));
  out.seq = static_cast<std::uint8_t>(get_bits(data, 40, 8));
  out.age_us = static_cast<std::uint16_t>(get_bits(data, 48, kAgeBits) * (kAgeStepNs / 1000));
  out.angle_order = static_cast<std::uint8_t>(get_bits(data, 60, kAngleOrderBits));
  out.look_alike = get_bits(data, 63, 1) != 0;
  return true;
}

inline bool decode_pose_fd(const std::uint8_t* data, std::uint8_t len, PoseFd& out) noexcept {
  if (len != kFdLen) return false;
  out.x_nm = static_cast<std::int32_t>(get_signed_bits(data, 0, 32));
  out.y_nm = static_cast<std::int32_t>(get_signed_bits(data, 32, 32));
  out.phi_mdeg = static_cast<std::int32_t>(get_signed_bits(data, 64, 32));
  out.score_e4 = static_cast<std::int16_t>(get_signed_bits(data, 96, 16));
  out.state = static_cast<WireState>(get_bits(data, 112, 8));
  out.reason_bits = static_cast<std::uint8_t>(get_bits(data, 120, 8));
  out.seq = static_cast<std::uint32_t>(get_bits(data, 128, 32));
  out.age_us = static_cast<std::uint32_t>(get_bits(data, 160, 32));
  out.psr_centi = static_cast<std::uint16_t>(get_bits(data, 192, 16));
  out.pattern_set = static_cast<std::uint8_t>(get_bits(data, 208, 8));
  out.target = static_cast<std::uint8_t>(get_bits(data, 216, 8));
  out.dwell_ns = static_cast<std::uint32_t>(get_bits(data, 224, 32));
  out.frame_seq = static_cast<std::uint32_t>(get_bits(data, 256, 32));
  out.scale_pm_per_px = static_cast<std::uint32_t>(get_bits(data, 288, 32));
  out.target_scale_e4 = static_cast<std::uint16_t>(get_bits(data, 320, 16));
  out.sigma_x_pm = static_cast<std::uint32_t>(get_bits(data, 336, 32));
  out.sigma_y_pm = static_cast<std::uint32_t>(get_bits(data, 368, 32));
  out.sigma_phi_udeg = static_cast<std::uint32_t>(get_bits(data, 400, 32));
  out.sigma_scale_e6 = static_cast<std::uint32_t>(get_bits(data, 432, 32));
  out.look_alike = get_bits(data, 464, 1) != 0;
  out.angle_order = static_cast<std::uint8_t>(get_bits(data, 472, 8));
  return true;
}

inline bool decode_pose_unc(const std::uint8_t* data, std::uint8_t len, PoseUnc& out) noexcept {
  if (len != kClassicLen) return false;
  out.sigma_x_dnm = static_cast<std::uint16_t>(get_bits(data, 0, kSigmaXyBits));
  out.sigma_y_dnm = static_cast<std::uint16_t>(get_bits(data, 12, kSigmaXyBits));
  out.sigma_phi_mdeg = static_cast<std::uint16_t>(get_bits(data, 24, kSigmaPhiBits));
  out.target_scale_e4 = static_cast<std::uint16_t>(get_bits(data, 35, kUncScaleBits));
  out.sigma_scale = static_cast<std::uint8_t>(get_bits(data, 49, kSigmaScaleBits));
  out.seq = static_cast<std::uint8_t>(get_bits(data, 56, 8));
  return true;
}

inline bool decode_heartbeat(const std::uint8_t* data, std::uint8_t len, Heartbeat& out) noexcept {
  if (len != kClassicLen) return false;
  out.state = static_cast<WireState>(get_bits(data, 0, 2));
  out.running = get_bits(data, 2, 1) != 0;
  out.bus_state = static_cast<BusState>(get_bits(data, 3, 2));
  out.fd = get_bits(data, 5, 1) != 0;
  out.output_fault = get_bits(data, 6, 1) != 0;
  out.stalled = get_bits(data, 7, 1) != 0;
  out.pattern_set = static_cast<std::uint8_t>(get_bits(data, 8, 4));
  out.bad_commands = static_cast<std::uint8_t>(get_bits(data, 12, 4));
  out.counter = static_cast<std::uint8_t>(get_bits(data, 16, 8));
  out.last_command_seq = static_cast<std::uint8_t>(get_bits(data, 24, 8));
  out.dwell_ns = static_cast<std::uint16_t>(get_bits(data, 32, 16));
  out.dropped_frames = static_cast<std::uint8_t>(get_bits(data, 48, 8));
  out.overruns = static_cast<std::uint8_t>(get_bits(data, 56, 4));
  out.tx_dropped = static_cast<std::uint8_t>(get_bits(data, 60, 4));
  return true;
}

// Validates everything a command frame carries; `out` is only meaningful when kOk.
inline CommandCheck decode_command(const std::uint8_t* data, std::uint8_t len, WireCommand& out) noexcept {
  if (len != kClassicLen) return CommandCheck::kBadLength;
  const auto op = static_cast<std::uint8_t>(get_bits(data, 0, 8));
  const auto arg = static_cast<std::uint8_t>(get_bits(data, 16, 8));
  const auto reserved = get_bits(data, 24, 8);
  const auto scale = static_cast<std::uint32_t>(get_bits(data, 32, 32));
  if (op < static_cast<std::uint8_t>(Opcode::kSelectPatternSet) || op > static_cast<std::uint8_t>(Opcode::kReacquire))
    return CommandCheck::kUnknownOpcode;
  if (reserved != 0) return CommandCheck::kReservedNotZero;
  const auto opcode = static_cast<Opcode>(op);
  switch (opcode) {
    case Opcode::kSelectPatternSet:
      if (arg >= kMaxPatternSets) return CommandCheck::kBadArgument;
      if (scale > kMaxScalePmPerPx) return CommandCheck::kBadScale;
      break;
    case Opcode::kStart:
    case Opcode::kStop:
      if (arg != 0) return CommandCheck::kBadArgument;
      if (scale != 0) return CommandCheck::kBadScale;
      break;
    case Opcode::kReacquire:
      if (arg >= kMaxTargets && arg != kAllTargets) return CommandCheck::kBadArgument;
      if (scale != 0) return CommandCheck::kBadScale;
      break;
  }
  out.opcode = opcode;
  out.seq = static_cast<std::uint8_t>(get_bits(data, 8, 8));
  out.arg = arg;
  out.scale_pm_per_px = scale;
  return CommandCheck::kOk;
}

}  // namespace sempose::ipc
