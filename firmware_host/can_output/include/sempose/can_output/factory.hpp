// Setup-time wiring from the config structs to channels and sinks (may allocate, may fail
// with a message naming the key and value). Nothing here runs on an RT thread.
#pragma once

#include <memory>
#include <string>

#include "sempose/can_output/can_pose_sink.hpp"
#include "sempose/config/can_config.hpp"
#include "sempose/config/gpio_config.hpp"
#include "sempose/hal/can_channel.hpp"
#include "sempose/hal/gpio_frame_sync.hpp"
#include "sempose/hal/gpio_outputs.hpp"
#include "sempose/rt/result.hpp"

namespace sempose::can_output {

struct CanOutput {
  std::unique_ptr<hal::CanChannel> channel;
  std::unique_ptr<CanPoseSink> sink;
  std::string description;  // one line for the log: "SocketCAN vcan0 (classic, sndbuf 16384)"
};

// can.interface set: SocketCAN on it. Otherwise (or when log_override is non-empty, i.e.
// `sempose run --can-log FILE`): the candump log (log_override or can.log_file), truncated
// unless keep_existing_log (the caller empties it once every output has opened).
rt::Status make_can_output(const config::CanConfig& cfg, const std::string& log_override, CanOutput& out,
                           bool keep_existing_log = false);

// gpio.chip empty or the line -1: returns ok with a null pointer (no GPIO).
rt::Status make_frame_sync(const config::GpioConfig& cfg, std::unique_ptr<hal::GpioFrameSync>& out);
rt::Status make_gpio_outputs(const config::GpioConfig& cfg, std::unique_ptr<hal::GpioOutputs>& out);

}  // namespace sempose::can_output
