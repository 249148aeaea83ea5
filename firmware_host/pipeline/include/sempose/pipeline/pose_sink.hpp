// The output stage's boundary: where poses go (CSV file, CAN bus, candump log) and where
// controller commands come from. Implementations: CsvPoseSink (pipeline), CanPoseSink
// (CAN over SocketCAN or a candump-log file). All methods after setup are RT-safe:
// noexcept, no allocation, never blocking — a full bus or file buffer drops and counts.
#pragma once

#include <cstdint>

#include "sempose/pose/track_state.hpp"

namespace sempose::pipeline {

// One pose as it leaves the tracker (full-field pixels, the README's conventions).
struct PoseRecord {
  std::uint64_t frame_seq = 0;      // scan-source sequence number of the frame
  std::uint32_t pose_seq = 0;       // per target, +1 per pose; wraps; gaps = dropped poses
  std::uint8_t target = 0;
  std::uint8_t pattern_set = 0;     // active magnification step
  pose::TrackState state = pose::TrackState::kAcquiring;
  std::uint8_t reason_bits = 0;     // pose::LostReason bits
  bool look_alike = false;           // see pose::PoseEstimate::look_alike (CAN: POSE_ATTR.look_alike)
  // phi_deg is known modulo 360°/angle_order (pose::PoseEstimate::angle_order; CSV angle_order,
  // CAN POSE_ATTR.angle_order): reported, so a reader knows what the angle means.
  std::uint8_t angle_order = 1;
  double x_px = 0;
  double y_px = 0;
  double phi_deg = 0;               // (-180, 180]
  float score = 0;                  // ZNCC in [-1, 1]
  float psr = 0;                    // peak-to-sidelobe ratio
  std::uint32_t dwell_ns = 0;       // dwell of the frame this pose came from
  double nm_per_px = 1;             // scale of the active magnification step
  double target_scale = 1;          // the target's size on screen over its pattern's (PoseEstimate::scale)
  // 1σ of the measured pose (PoseEstimate::sigma_*; 0 = not measured): px, deg, scale.
  double sigma_x_px = 0, sigma_y_px = 0, sigma_phi_deg = 0, sigma_scale = 0;
  std::int64_t t_scan_end_ns = 0;
  // When the beam passed the target (PoseEstimate::t_beam_ns): the time the pose is valid for
  // (the CSV's t_ns, CAN's age from it); the scan's end when the tracker did not say.
  std::int64_t t_beam_ns = 0;
  std::int64_t t_pose_done_ns = 0;
  // Simulated sources only: where the target really was (validation, never on the wire).
  bool truth_present = false;
  double truth_x_px = 0;
  double truth_y_px = 0;
  double truth_phi_deg = 0;
};

// Pipeline state for the heartbeat/status frame.
struct PipelineStatus {
  pose::TrackState state = pose::TrackState::kAcquiring;  // of target 0 (worst over targets)
  std::uint8_t pattern_set = 0;
  bool running = true;              // false after a stop command
  std::uint32_t dwell_ns = 0;
  std::uint32_t dropped_frames = 0;
  std::uint32_t overruns = 0;
  // Acknowledgement: the seq of the last command that took effect, and how many valid
  // commands were refused because they named something that does not exist (a pattern set
  // or target not configured) or were lost to a full command ring.
  std::uint8_t last_command_seq = 0;
  std::uint32_t commands_rejected = 0;
  std::uint8_t fault_bits = 0;      // kFault* below: reported faults (heartbeat, summary)
};

inline constexpr std::uint8_t kFaultOutputWrite = 1;    // a file output (CSV, candump log) failed to write
inline constexpr std::uint8_t kFaultSourceStalled = 2;  // no frame from the scan source for too long
inline constexpr std::uint8_t kFaultStageStalled = 4;   // an RT stage made no progress (service watchdog)

enum class CommandKind : std::uint8_t {
  kSelectPatternSet = 0,  // arg = pattern set / magnification step; nm_per_px = its scale
  kStart,
  kStop,
  kReacquire,             // target = which one (0xFF = all)
};

struct Command {
  CommandKind kind = CommandKind::kStart;
  std::uint8_t seq = 0;  // the controller's sequence number, echoed once the command took effect
  std::uint8_t target = 0xFF;
  std::uint8_t arg = 0;
  double nm_per_px = 0;  // 0 = keep the configured value
};

enum class PublishResult : std::uint8_t { kSent = 0, kDropped, kError };

class PoseSink {
 public:
  virtual ~PoseSink() = default;
  // Sends one pose; t_now_ns is the send time (CLOCK_MONOTONIC or the virtual clock).
  virtual PublishResult publish(const PoseRecord& pose, std::int64_t t_now_ns) noexcept = 0;
  // Called every output-stage cycle: heartbeats, bus-state updates, reading commands.
  virtual void service(const PipelineStatus& /*status*/, std::int64_t /*t_now_ns*/) noexcept {}
  // Hands out one pending valid command, if any (bad ones are counted and dropped).
  virtual bool next_command(Command& /*out*/) noexcept { return false; }
  // Flushes buffered output (non-RT, at shutdown).
  virtual void flush() {}
};

}  // namespace sempose::pipeline
