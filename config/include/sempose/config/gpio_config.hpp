// GPIO settings (libgpiod). YAML section `gpio:` (read_gpio). Absent section or empty chip
// = no GPIO at all; each line is optional (-1).
#pragma once

#include <cstdint>
#include <string>

namespace sempose::config {

class Section;

struct GpioConfig {
  std::string chip;                          // "gpiochip0", "/dev/gpiochip0" or a label; empty = none
  std::int32_t frame_sync_line = -1;         // rising edge = ROI scan complete; -1 = time it instead
  std::int32_t pose_valid_line = -1;         // output: active while TRACKING
  std::int32_t heartbeat_line = -1;          // output: toggled on every pose
  bool active_low = false;                   // applies to all three lines
  std::int32_t frame_sync_timeout_us = 20000;// after the expected scan end; then the frame is flagged
  std::string consumer = "sempose";          // label shown by gpioinfo

  bool enabled() const noexcept { return !chip.empty(); }
};

void read_gpio(Section& s, GpioConfig& out);

}  // namespace sempose::config
