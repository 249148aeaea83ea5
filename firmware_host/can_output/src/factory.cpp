// Setup-time wiring of CAN and GPIO outputs from the config. See factory.hpp.
#include "sempose/can_output/factory.hpp"

#include "sempose/hal/can_candump_log.hpp"
#include "sempose/hal/can_socket_channel.hpp"

namespace sempose::can_output {

rt::Status make_can_output(const config::CanConfig& cfg, const std::string& log_override, CanOutput& out,
                           bool keep_existing_log) {
  rt::Status st;
  const ipc::IdMap ids{cfg.base_id, cfg.effective_command_id()};
  if (!ids.valid()) {
    return rt::Status::failure("can.base_id " + std::to_string(cfg.base_id) + " / can.command_id " +
                               std::to_string(cfg.effective_command_id()) +
                               ": ids must fit 11 bits and not collide");
  }
  if (!cfg.interface.empty() && log_override.empty()) {
    hal::SocketCanOptions o;
    o.interface = cfg.interface;
    o.fd = cfg.fd == "on" ? hal::CanFdMode::kOn : cfg.fd == "off" ? hal::CanFdMode::kOff : hal::CanFdMode::kAuto;
    o.sndbuf_bytes = cfg.sndbuf_bytes;
    o.rx_id = static_cast<int>(ids.command);
    auto ch = hal::SocketCanChannel::open(o, st);
    if (!ch) return st;
    out.description = "SocketCAN " + cfg.interface + " (" + (ch->fd_enabled() ? "CAN FD" : "classic CAN") +
                      ", MTU " + std::to_string(ch->mtu()) + ", SO_SNDBUF " + std::to_string(ch->sndbuf_bytes()) +
                      (cfg.bitrate ? ", " + std::to_string(cfg.bitrate) + " bit/s" : std::string()) + ")";
    out.channel = std::move(ch);
  } else {
    hal::CandumpLogOptions o;
    o.path = log_override.empty() ? cfg.log_file : log_override;
    o.channel_name = cfg.log_channel;
    o.buffer_bytes = cfg.log_buffer_bytes;
    o.wall_clock = cfg.log_timestamps == "wall";
    o.fd = cfg.fd == "on";  // a log has no MTU: FD frames only when asked for explicitly
    o.keep_existing = keep_existing_log;
    auto ch = hal::CandumpLogChannel::open(o, st);
    if (!ch) {
      // The log named by the option the user typed, not the key it stands in for.
      const std::string key = "can.log_file";
      if (!log_override.empty() && st.message.rfind(key, 0) == 0) st.message.replace(0, key.size(), "--can-log");
      return st;
    }
    out.description = "candump log " + o.path + " (" + (o.fd ? "CAN FD" : "classic CAN") + ", as " + o.channel_name + ")";
    out.channel = std::move(ch);
  }
  CanSinkOptions so;
  so.ids = ids;
  so.heartbeat_period_ns = static_cast<std::int64_t>(1e9 / cfg.heartbeat_hz);
  so.max_commands_per_cycle = cfg.max_commands_per_cycle;
  out.sink = std::make_unique<CanPoseSink>(*out.channel, so);
  return rt::Status::success();
}

rt::Status make_frame_sync(const config::GpioConfig& cfg, std::unique_ptr<hal::GpioFrameSync>& out) {
  out.reset();
  if (!cfg.enabled() || cfg.frame_sync_line < 0) return rt::Status::success();
  rt::Status st;
  out = hal::GpioFrameSync::open({cfg.chip, cfg.frame_sync_line, cfg.active_low, cfg.consumer}, st);
  return st;
}

rt::Status make_gpio_outputs(const config::GpioConfig& cfg, std::unique_ptr<hal::GpioOutputs>& out) {
  out.reset();
  if (!cfg.enabled() || (cfg.pose_valid_line < 0 && cfg.heartbeat_line < 0)) return rt::Status::success();
  rt::Status st;
  out = hal::GpioOutputs::open({cfg.chip, cfg.pose_valid_line, cfg.heartbeat_line, cfg.active_low, cfg.consumer}, st);
  return st;
}

}  // namespace sempose::can_output
