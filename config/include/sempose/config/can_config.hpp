// CAN output settings. YAML section `can:` (read_can). Absent interface = no bus: the same
// frames go to a candump -l log file instead (so the demo runs on any machine).
#pragma once

#include <cstdint>
#include <string>

namespace sempose::config {

class Section;

struct CanConfig {
  std::string interface;                    // "can0", "vcan0"; empty = write the candump log
  std::string log_file = "sempose_can.log"; // candump -l log when interface is empty
  std::string log_channel = "can0";         // interface name written on each log line
  std::string log_timestamps = "source";    // "source": pipeline clock; "wall": CLOCK_REALTIME
  std::uint32_t log_buffer_bytes = 1u << 20;// RT-side ring for log lines (flushed off the RT thread)
  std::uint32_t base_id = 0x100;            // first id of the block (standard 11-bit ids)
  std::int32_t command_id = -1;             // -1 = base_id + 0x50
  double heartbeat_hz = 10.0;
  std::string fd = "off";                   // "off" (classic) | "auto" (FD if the MTU is 72) | "on" (require FD)
  std::uint32_t bitrate = 0;                // informational (set with `ip link`); 0 = not stated
  std::int32_t sndbuf_bytes = 16384;        // SO_SNDBUF; small so a full queue answers EAGAIN
  std::int32_t max_commands_per_cycle = 8;  // bound on command frames read per output cycle

  std::uint32_t effective_command_id() const noexcept {
    return command_id >= 0 ? static_cast<std::uint32_t>(command_id) : base_id + 0x50;
  }
};

// Reads `can:`; base_id/command_id accept hex ("0x100") or decimal; checks that every id
// fits 11 bits and the command id does not collide with an id sempose sends.
void read_can(Section& s, CanConfig& out);

}  // namespace sempose::config
