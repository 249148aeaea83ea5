#include <cstdlib>
#include <string>

#include "sempose/config/can_config.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {
namespace {

// An id as hex ("0x150") or decimal; `lo`..`hi` inclusive. Returns false (error added) if bad.
bool read_id(Section& s, const char* key, std::int64_t& out, std::int64_t lo, std::int64_t hi) {
  std::string text;
  s.opt(key, text);
  if (!s.has(key)) return true;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 0);
  if (text.empty() || end == nullptr || *end != '\0') {
    s.error(key, "'" + text + "' is not a number (write 0x100 or 256)");
    return false;
  }
  if (v < lo || v > hi) {
    s.error(key, text + " is outside the allowed range " + describe_range(static_cast<double>(lo), static_cast<double>(hi)));
    return false;
  }
  out = v;
  return true;
}

}  // namespace

void read_can(Section& s, CanConfig& out) {
  s.opt("interface", out.interface);
  // The kernel's rule for a network interface name (dev_valid_name: at most IFNAMSIZ - 1 = 15
  // bytes, not "." or "..", no '/', ':' or white space): a 16-character name passed here, run
  // refused it unlocated and check-rt offered an `ip link add` that fails (hostile round 11).
  if (!out.interface.empty() &&
      (out.interface.size() > 15 || out.interface == "." || out.interface == ".." ||
       out.interface.find_first_of("/: \t\n\r\v\f") != std::string::npos))
    s.error("interface", "'" + out.interface + "' is not a network interface name (1..15 characters, not '.' or '..', no '/', ':' or spaces)");
  s.opt("log_file", out.log_file);
  s.opt("log_channel", out.log_channel);
  s.opt_choice("log_timestamps", out.log_timestamps, {"source", "wall"});
  s.opt("log_buffer_bytes", out.log_buffer_bytes, 4096u, 1u << 28);
  std::int64_t base = out.base_id;
  // base + 0x40 (heartbeat) must stay a standard id.
  if (read_id(s, "base_id", base, 0, 0x7FF - 0x40)) out.base_id = static_cast<std::uint32_t>(base);
  std::int64_t cmd = out.command_id;
  if (read_id(s, "command_id", cmd, -1, 0x7FF)) out.command_id = static_cast<std::int32_t>(cmd);
  s.opt("heartbeat_hz", out.heartbeat_hz, 0.1, 1000.0);
  s.opt_choice("fd", out.fd, {"auto", "off", "on"});
  s.opt("bitrate", out.bitrate, 0u, 8'000'000u);
  s.opt("sndbuf_bytes", out.sndbuf_bytes, 0, 1 << 24);
  s.opt("max_commands_per_cycle", out.max_commands_per_cycle, 1, 64);
  if (out.log_channel.empty() || out.log_channel.size() > 15 ||
      out.log_channel.find_first_of(" \t#()") != std::string::npos)
    s.error("log_channel", "'" + out.log_channel + "' must be 1..15 characters without spaces, '#' or parentheses");

  const std::uint32_t cmd_id = out.effective_command_id();
  if (cmd_id > 0x7FF) {
    s.error(out.command_id >= 0 ? "command_id" : "base_id",
            "command id " + std::to_string(cmd_id) + " (base_id + 0x50) is above 0x7FF; set can.command_id");
  } else if (cmd_id >= out.base_id && cmd_id < out.base_id + 0x40 && (cmd_id - out.base_id) % 0x10 <= 3) {
    // +3 is POSE_UNC (it passed here and was refused later by the CAN setup, without file:line
    // or what it collides with; hostile round 11).
    static const char* const kFrames[] = {"POSE_XY", "POSE_ATTR", "POSE_FD", "POSE_UNC"};
    s.error("command_id", std::to_string(cmd_id) + " collides with target " + std::to_string((cmd_id - out.base_id) / 0x10) +
                              "'s " + kFrames[(cmd_id - out.base_id) % 0x10] +
                              " id (pose frames: base_id + 0x10*target + 0..3)");
  } else if (cmd_id == out.base_id + 0x40) {
    s.error("command_id", std::to_string(cmd_id) + " collides with the heartbeat id (base_id + 0x40)");
  }
}

}  // namespace sempose::config
