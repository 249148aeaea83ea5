#include <string>

#include "sempose/config/gpio_config.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {

void read_gpio(Section& s, GpioConfig& out) {
  constexpr std::int32_t kMaxLine = 1023;
  s.opt("chip", out.chip);
  s.opt("frame_sync_line", out.frame_sync_line, -1, kMaxLine);
  s.opt("pose_valid_line", out.pose_valid_line, -1, kMaxLine);
  s.opt("heartbeat_line", out.heartbeat_line, -1, kMaxLine);
  s.opt("active_low", out.active_low);
  s.opt("frame_sync_timeout_us", out.frame_sync_timeout_us, 100, 10'000'000);
  s.opt("consumer", out.consumer);
  const char* lines[] = {"frame_sync_line", "pose_valid_line", "heartbeat_line"};
  const std::int32_t values[] = {out.frame_sync_line, out.pose_valid_line, out.heartbeat_line};
  for (int i = 0; i < 3; ++i) {
    if (values[i] < 0) continue;
    if (out.chip.empty()) {
      s.error(lines[i], std::to_string(values[i]) + " is set but gpio.chip is empty (name the chip, e.g. gpiochip0)");
    }
    for (int j = 0; j < i; ++j) {
      if (values[j] == values[i])
        s.error(lines[i], std::to_string(values[i]) + " is the same line as gpio." + lines[j]);
    }
  }
}

}  // namespace sempose::config
