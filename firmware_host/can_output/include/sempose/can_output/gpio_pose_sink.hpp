// A PoseSink decorator that drives the GPIO status outputs: "pose valid" active while every
// target seen so far is TRACKING (and the pipeline runs), and a heartbeat line toggled on each
// pose, so an amplifier can stop when sempose stalls. Everything else is forwarded.
#pragma once

#include <cstdint>

#include "sempose/hal/gpio_outputs.hpp"
#include "sempose/pipeline/pose_sink.hpp"

namespace sempose::can_output {

class GpioPoseSink final : public pipeline::PoseSink {
 public:
  GpioPoseSink(pipeline::PoseSink& inner, hal::StatusOutputs& outputs) noexcept : inner_(inner), outputs_(outputs) {}

  pipeline::PublishResult publish(const pipeline::PoseRecord& pose, std::int64_t t_now_ns) noexcept override {
    const auto r = inner_.publish(pose, t_now_ns);
    if (pose.target < 8) {
      const auto bit = static_cast<std::uint8_t>(1u << pose.target);
      seen_ |= bit;
      if (pose.state == pose::TrackState::kTracking) tracking_ |= bit;
      else tracking_ = static_cast<std::uint8_t>(tracking_ & ~bit);
    }
    outputs_.set_pose_valid(running_ && tracking_ == seen_);
    outputs_.toggle_heartbeat();
    return r;
  }
  void service(const pipeline::PipelineStatus& status, std::int64_t t_now_ns) noexcept override {
    running_ = status.running;
    // A stalled source gives no new pose: the last TRACKING must not keep "pose valid" up.
    if (status.fault_bits & pipeline::kFaultSourceStalled) {
      tracking_ = 0;
      outputs_.set_pose_valid(false);
    }
    if (!running_) outputs_.set_pose_valid(false);
    inner_.service(status, t_now_ns);
  }
  bool next_command(pipeline::Command& out) noexcept override { return inner_.next_command(out); }
  void flush() override { inner_.flush(); }

 private:
  pipeline::PoseSink& inner_;
  hal::StatusOutputs& outputs_;
  std::uint8_t seen_ = 0;
  std::uint8_t tracking_ = 0;
  bool running_ = true;
};

}  // namespace sempose::can_output
