// Status outputs for the amplifier side: "pose valid" (high while TRACKING) and a heartbeat
// line toggled on every pose, so hardware can stop the piezos when sempose stalls.
// libgpiod v1 C API: lines requested as outputs at setup; gpiod_line_set_value is one
// non-blocking ioctl — RT-safe. Unchanged values are not written again.
#pragma once

#include <memory>
#include <string>

#include "sempose/rt/result.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace sempose::hal {

class StatusOutputs {
 public:
  virtual ~StatusOutputs() = default;
  virtual void set_pose_valid(bool valid) noexcept = 0;
  virtual void toggle_heartbeat() noexcept = 0;
};

struct GpioOutputOptions {
  std::string chip;
  int pose_valid_line = -1;   // -1: not used
  int heartbeat_line = -1;    // -1: not used
  bool active_low = false;
  std::string consumer = "sempose";
};

class GpioOutputs final : public StatusOutputs {
 public:
  // Setup: requests the configured lines as outputs, initially inactive (pose not valid).
  static std::unique_ptr<GpioOutputs> open(const GpioOutputOptions& options, rt::Status& status);
  ~GpioOutputs() override;  // drives pose-valid inactive, then releases the lines

  void set_pose_valid(bool valid) noexcept override;
  void toggle_heartbeat() noexcept override;
  bool pose_valid() const noexcept { return valid_ == 1; }
  int heartbeat_level() const noexcept { return heartbeat_; }
  std::uint64_t write_errors() const noexcept { return write_errors_; }

 private:
  GpioOutputs() = default;
  gpiod_chip* chip_ = nullptr;
  gpiod_line* valid_line_ = nullptr;
  gpiod_line* heartbeat_line_ = nullptr;
  int valid_ = 0;
  int heartbeat_ = 0;
  std::uint64_t write_errors_ = 0;
};

}  // namespace sempose::hal
