// Pose-valid and heartbeat outputs over the libgpiod v1 C API. See gpio_outputs.hpp.
#include "sempose/hal/gpio_outputs.hpp"

#include <gpiod.h>

#include <cerrno>
#include <cstring>

#include "sempose/hal/gpio_chip_open.hpp"

namespace sempose::hal {
namespace {

gpiod_line* request_output(gpiod_chip* chip, int offset, const GpioOutputOptions& o, const char* key,
                           rt::Status& status) {
  const std::string where = "gpio.chip '" + o.chip + "' gpio." + key + " " + std::to_string(offset) + ": ";
  if (offset < 0 || static_cast<unsigned>(offset) >= gpiod_chip_num_lines(chip)) {
    status = rt::Status::failure(where + "line offset outside the chip's range [0, " +
                                 std::to_string(gpiod_chip_num_lines(chip)) + ")");
    return nullptr;
  }
  gpiod_line* line = gpiod_chip_get_line(chip, static_cast<unsigned>(offset));
  const int flags = o.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (line == nullptr || gpiod_line_request_output_flags(line, o.consumer.c_str(), flags, 0) != 0) {
    status = rt::Status::failure(where + "cannot request as output: " + std::strerror(errno) +
                                 " (line busy? `gpioinfo` shows its consumer)");
    return nullptr;
  }
  return line;
}

}  // namespace

std::unique_ptr<GpioOutputs> GpioOutputs::open(const GpioOutputOptions& o, rt::Status& status) {
  std::unique_ptr<GpioOutputs> g(new GpioOutputs());
  std::string why;
  g->chip_ = open_gpio_chip(o.chip, why);
  if (g->chip_ == nullptr) {
    status = rt::Status::failure("gpio.chip '" + o.chip + "': cannot open the chip: " + why +
                                 " (`gpiodetect` lists chips)");
    return nullptr;
  }
  if (o.pose_valid_line >= 0) {
    g->valid_line_ = request_output(g->chip_, o.pose_valid_line, o, "pose_valid_line", status);
    if (g->valid_line_ == nullptr) return nullptr;
  }
  if (o.heartbeat_line >= 0) {
    if (o.heartbeat_line == o.pose_valid_line) {
      status = rt::Status::failure("gpio.heartbeat_line " + std::to_string(o.heartbeat_line) +
                                   ": the same line as gpio.pose_valid_line");
      return nullptr;
    }
    g->heartbeat_line_ = request_output(g->chip_, o.heartbeat_line, o, "heartbeat_line", status);
    if (g->heartbeat_line_ == nullptr) return nullptr;
  }
  status = rt::Status::success();
  return g;
}

GpioOutputs::~GpioOutputs() {
  if (valid_line_ != nullptr) {
    gpiod_line_set_value(valid_line_, 0);  // stopped: the pose is no longer valid
    gpiod_line_release(valid_line_);
  }
  if (heartbeat_line_ != nullptr) gpiod_line_release(heartbeat_line_);
  if (chip_ != nullptr) gpiod_chip_close(chip_);
}

void GpioOutputs::set_pose_valid(bool valid) noexcept {
  const int v = valid ? 1 : 0;
  if (v == valid_) return;
  valid_ = v;
  if (valid_line_ != nullptr && gpiod_line_set_value(valid_line_, v) != 0) ++write_errors_;
}

void GpioOutputs::toggle_heartbeat() noexcept {
  heartbeat_ ^= 1;
  if (heartbeat_line_ != nullptr && gpiod_line_set_value(heartbeat_line_, heartbeat_) != 0) ++write_errors_;
}

}  // namespace sempose::hal
