// CAN pose sink: encodes poses and heartbeats (ipc/), reads and validates commands.
#include "sempose/can_output/can_pose_sink.hpp"

#include <cmath>

namespace sempose::can_output {
namespace {

ipc::WireState to_wire(pose::TrackState s) noexcept {
  switch (s) {
    case pose::TrackState::kTracking: return ipc::WireState::kTracking;
    case pose::TrackState::kAcquiring: return ipc::WireState::kAcquiring;
    case pose::TrackState::kLost: return ipc::WireState::kLost;
    case pose::TrackState::kUncertain: return ipc::WireState::kUncertain;
  }
  return ipc::WireState::kLost;
}

}  // namespace

CanPoseSink::CanPoseSink(hal::CanChannel& channel, const CanSinkOptions& options) noexcept
    : channel_(channel), options_(options), fd_(channel.fd_enabled()) {
  if (options_.heartbeat_period_ns <= 0) options_.heartbeat_period_ns = 100'000'000;
  if (options_.max_commands_per_cycle <= 0) options_.max_commands_per_cycle = 1;
}

ipc::PoseValues CanPoseSink::to_values(const pipeline::PoseRecord& p, std::int64_t t_now_ns) noexcept {
  ipc::PoseValues v;
  v.x_nm = p.x_px * p.nm_per_px;
  v.y_nm = p.y_px * p.nm_per_px;
  v.phi_deg = p.phi_deg;
  v.score = p.score;
  v.psr = p.psr;
  v.state = to_wire(p.state);
  v.reason_bits = p.reason_bits;
  v.look_alike = p.look_alike;
  v.angle_order = p.angle_order;
  // A pose that is not a number is not a pose: say so instead of sending a plausible 0.
  if (!std::isfinite(v.x_nm) || !std::isfinite(v.y_nm) || !std::isfinite(v.phi_deg) || !std::isfinite(v.score)) {
    v.x_nm = v.y_nm = v.phi_deg = v.score = 0;
    v.state = ipc::WireState::kLost;
    v.reason_bits = static_cast<std::uint8_t>(v.reason_bits | pose::kReasonBadFrame);
  }
  if (!std::isfinite(v.psr)) v.psr = 0;
  // A position POSE_XY cannot carry saturates at ±134 mm: never a TRACKING pose (with nm_per_px
  // 1e6 every pose went out pinned there, TRACKING; hostile round 11). Setup refuses a field
  // that does not fit (make_trackers); a SELECT's nm/px can still exceed it.
  if ((std::fabs(v.x_nm) > ipc::kXyMaxNm || std::fabs(v.y_nm) > ipc::kXyMaxNm) && v.state == ipc::WireState::kTracking) {
    v.state = ipc::WireState::kUncertain;
    v.reason_bits = static_cast<std::uint8_t>(v.reason_bits | pose::kReasonOutOfField);
  }
  v.seq = p.pose_seq;
  // Age from when the beam passed the target, the time the pose is valid for (a full-field
  // search frame's pose can be tens of ms older than its scan's end).
  v.age_ns = t_now_ns - (p.t_beam_ns != 0 ? p.t_beam_ns : p.t_scan_end_ns);
  v.pattern_set = p.pattern_set;
  v.target = p.target;
  v.dwell_ns = p.dwell_ns;
  v.frame_seq = p.frame_seq;
  v.nm_per_px = std::isfinite(p.nm_per_px) ? p.nm_per_px : 0;
  v.target_scale = std::isfinite(p.target_scale) ? p.target_scale : 0;
  // σ in nm at the active step's nm/px (a σ that is not a finite number is "not measured": 0).
  auto finite_or_0 = [](double d) { return std::isfinite(d) && d > 0 ? d : 0.0; };
  v.sigma_x_nm = finite_or_0(p.sigma_x_px * v.nm_per_px);
  v.sigma_y_nm = finite_or_0(p.sigma_y_px * v.nm_per_px);
  v.sigma_phi_deg = finite_or_0(p.sigma_phi_deg);
  v.sigma_scale = finite_or_0(p.sigma_scale);
  return v;
}

pipeline::PublishResult CanPoseSink::publish(const pipeline::PoseRecord& pose, std::int64_t t_now_ns) noexcept {
  if (pose.target >= ipc::kMaxTargets) {
    bump(counters_.poses_dropped);
    return pipeline::PublishResult::kError;
  }
  const ipc::PoseValues v = to_values(pose, t_now_ns);
  hal::CanFrame f;
  hal::CanSendResult r;
  if (fd_) {
    f.id = options_.ids.pose_fd(pose.target);
    f.len = ipc::kFdLen;
    f.flags = hal::CanFrame::kFd;
    ipc::encode_pose_fd(v, f.data);
    r = channel_.send(f, t_now_ns);
  } else {
    f.id = options_.ids.pose_xy(pose.target);
    f.len = ipc::kClassicLen;
    ipc::encode_pose_xy(v, f.data);
    r = channel_.send(f, t_now_ns);
    // Without its XY frame an ATTR frame is useless to the controller: skip it then.
    if (r == hal::CanSendResult::kSent) {
      f.id = options_.ids.pose_attr(pose.target);
      ipc::encode_pose_attr(v, f.data);
      r = channel_.send(f, t_now_ns);
    }
    if (r == hal::CanSendResult::kSent) {
      f.id = options_.ids.pose_unc(pose.target);
      ipc::encode_pose_unc(v, f.data);
      r = channel_.send(f, t_now_ns);
    }
  }
  if (r == hal::CanSendResult::kSent) {
    bump(counters_.poses_sent);
    return pipeline::PublishResult::kSent;
  }
  bump(counters_.poses_dropped);
  return r == hal::CanSendResult::kDropped ? pipeline::PublishResult::kDropped : pipeline::PublishResult::kError;
}

void CanPoseSink::send_heartbeat(const pipeline::PipelineStatus& s, std::int64_t t_now_ns) noexcept {
  const auto& cc = channel_.counters();
  ipc::Heartbeat h;
  h.state = to_wire(s.state);
  h.running = s.running;
  h.bus_state = static_cast<ipc::BusState>(channel_.bus_state());
  h.fd = fd_;
  h.pattern_set = s.pattern_set;
  // Every command that did not take effect: malformed, lost to a full ring, or naming a
  // pattern set or target that does not exist.
  const std::uint64_t refused = counters_.bad_commands.load(std::memory_order_relaxed) +
                                counters_.commands_overflowed.load(std::memory_order_relaxed) + s.commands_rejected;
  h.bad_commands = static_cast<std::uint8_t>(refused & 0xF);
  h.counter = heartbeat_counter_++;
  // Acknowledge only what took effect (the pipeline echoes the seq once applied).
  h.last_command_seq = s.last_command_seq;
  h.output_fault = (s.fault_bits & pipeline::kFaultOutputWrite) != 0;
  h.stalled = (s.fault_bits & (pipeline::kFaultSourceStalled | pipeline::kFaultStageStalled)) != 0;
  h.dwell_ns = static_cast<std::uint16_t>(s.dwell_ns > 0xFFFF ? 0xFFFF : s.dwell_ns);
  h.dropped_frames = static_cast<std::uint8_t>(s.dropped_frames & 0xFF);
  h.overruns = static_cast<std::uint8_t>(s.overruns & 0xF);
  const std::uint64_t not_sent = cc.tx_dropped.load(std::memory_order_relaxed) + cc.tx_errors.load(std::memory_order_relaxed);
  h.tx_dropped = static_cast<std::uint8_t>(not_sent & 0xF);
  hal::CanFrame f;
  f.id = options_.ids.heartbeat();
  f.len = ipc::kClassicLen;
  ipc::encode_heartbeat(h, f.data);
  if (channel_.send(f, t_now_ns) == hal::CanSendResult::kSent) bump(counters_.heartbeats_sent);
  else bump(counters_.heartbeats_dropped);
}

bool CanPoseSink::to_command(const ipc::WireCommand& w, pipeline::Command& out) noexcept {
  out = pipeline::Command{};
  switch (w.opcode) {
    case ipc::Opcode::kSelectPatternSet:
      out.kind = pipeline::CommandKind::kSelectPatternSet;
      out.arg = w.arg;
      out.nm_per_px = static_cast<double>(w.scale_pm_per_px) / 1000.0;
      return true;
    case ipc::Opcode::kStart: out.kind = pipeline::CommandKind::kStart; return true;
    case ipc::Opcode::kStop: out.kind = pipeline::CommandKind::kStop; return true;
    case ipc::Opcode::kReacquire:
      out.kind = pipeline::CommandKind::kReacquire;
      out.target = w.arg;
      return true;
  }
  return false;
}

void CanPoseSink::read_commands() noexcept {
  hal::CanFrame f;
  for (int i = 0; i < options_.max_commands_per_cycle && channel_.receive(f); ++i) {
    if (f.id != options_.ids.command) {
      bump(counters_.non_command_frames);
      continue;
    }
    ipc::WireCommand w;
    // RTR, FD and extended frames on the command id are malformed commands (counted), not
    // commands: the protocol is classic 11-bit data frames only.
    ipc::CommandCheck check = ipc::CommandCheck::kBadLength;
    if (!f.remote() && !f.fd() && !f.extended()) check = ipc::decode_command(f.data, f.len, w);
    pipeline::Command cmd;
    if (check != ipc::CommandCheck::kOk || !to_command(w, cmd)) {
      counters_.last_bad_reason.store(static_cast<std::uint8_t>(check), std::memory_order_relaxed);
      bump(counters_.bad_commands);
      continue;
    }
    counters_.last_command_seq.store(w.seq, std::memory_order_relaxed);  // received (the ack waits for the effect)
    cmd.seq = w.seq;
    if (commands_.try_push(cmd)) bump(counters_.commands_accepted);
    else bump(counters_.commands_overflowed);
  }
}

void CanPoseSink::service(const pipeline::PipelineStatus& status, std::int64_t t_now_ns) noexcept {
  read_commands();  // also folds error frames into the channel's bus state
  if (!heartbeat_started_ || t_now_ns >= next_heartbeat_ns_) {
    send_heartbeat(status, t_now_ns);
    const std::int64_t period = options_.heartbeat_period_ns;
    // Keep a fixed rate; after a long gap restart the grid instead of sending a burst.
    next_heartbeat_ns_ = (!heartbeat_started_ || t_now_ns - next_heartbeat_ns_ >= period)
                             ? t_now_ns + period
                             : next_heartbeat_ns_ + period;
    heartbeat_started_ = true;
  }
}

bool CanPoseSink::next_command(pipeline::Command& out) noexcept { return commands_.try_pop(out); }

}  // namespace sempose::can_output
