// The pipeline's setup and threads (pipeline.hpp); the stages' loops are in
// pipeline_acquisition.cpp, pipeline_correlation.cpp and pipeline_output.cpp.
#include "sempose/pipeline/pipeline.hpp"

#include <algorithm>
#include <stdexcept>

#include "sempose/pose/tracker.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"
#include "cpu_relax.hpp"

namespace sempose::pipeline {
Pipeline::Pipeline(const config::PipelineConfig& pipeline, const config::GovernorConfig& governor,
                   hal::ScanSource& source, std::vector<pose::Tracker*> trackers, PoseSink& sink,
                   const StageClock& clock)
    : config_(pipeline),
      clock_(clock),
      source_(source),
      trackers_(std::move(trackers)),
      sink_(sink),
      step_(governor, source.limits(), trackers_, clock),
      spin_(clock.real_time() && pipeline.polling == "spin"),
      sleep_polling_(clock.real_time() && pipeline.polling != "spin"),
      frame_ring_depth_(std::clamp<std::uint32_t>(pipeline.frame_ring, 2, kFrameRingCapacity)),
      pose_ring_depth_(std::clamp<std::uint32_t>(pipeline.pose_ring, 2, kPoseRingCapacity)),
      pool_(frame_pool_slots_for(pipeline), frame_slot_pixels(source.limits())) {
  if (trackers_.empty() || trackers_.size() > static_cast<std::size_t>(hal::kMaxTargets)) {
    throw std::invalid_argument("pipeline: 1 to " + std::to_string(hal::kMaxTargets) +
                                " targets are supported, got " + std::to_string(trackers_.size()));
  }
  for (auto* t : trackers_) {
    if (t == nullptr) throw std::invalid_argument("pipeline: a target has no tracker");
  }
  if (pipeline.schedule.size() > kMaxSchedule) {
    throw std::invalid_argument("pipeline.schedule: at most " + std::to_string(kMaxSchedule) + " entries");
  }
  for (int t : pipeline.schedule) {
    if (t < 0 || t >= static_cast<int>(trackers_.size())) {
      throw std::invalid_argument("pipeline.schedule: " + std::to_string(t) + " is not a target index");
    }
    schedule_[schedule_len_++] = static_cast<std::uint8_t>(t);
  }
  if (schedule_len_ == 0) {
    for (std::size_t t = 0; t < trackers_.size(); ++t) schedule_[schedule_len_++] = static_cast<std::uint8_t>(t);
  }
  for (std::size_t i = 0; i < pool_.size(); ++i) {
    pool_.transfer(static_cast<hal::FramePool::Index>(i), rt::SlotOwner::kFree, kAcq);
    free_slots_.try_push(static_cast<hal::FramePool::Index>(i));  // acquisition collects them at start
  }
  status_.publish(StatusWords{0, static_cast<std::uint8_t>(pose::TrackState::kAcquiring), 0, 1, 0, 0});
  for (std::size_t t = 0; t < trackers_.size(); ++t) {
    last_state_[t] = pose::TrackState::kAcquiring;
    publish_plan(static_cast<std::uint8_t>(t), true);
  }
}

Pipeline::~Pipeline() {
  request_stop();
  join();
}

void Pipeline::idle_wait(std::int64_t until_ns) const noexcept {
  if (spin_) {
    for (int i = 0; i < 64; ++i) cpu_relax();
    return;
  }
  const std::int64_t t = rt::now_ns();
  const std::int64_t latest = t + idle_sleep_ns();
  const std::int64_t earliest = t + 5 * rt::kNsPerUs;
  rt::sleep_until_ns(std::clamp(until_ns, earliest, latest));
}

std::int64_t Pipeline::idle_sleep_ns() const noexcept {
  return static_cast<std::int64_t>(config_.idle_sleep_us) * rt::kNsPerUs;
}

std::int64_t Pipeline::whole_idle_sleep() const noexcept { return rt::now_ns() + idle_sleep_ns(); }

void Pipeline::publish_plan(std::uint8_t target, bool enabled) noexcept {
  const hal::ScanRequest next = step_.next_scan(target);
  ScanPlan plan{};
  plan.x = next.roi.x;
  plan.y = next.roi.y;
  plan.w = next.roi.w;
  plan.h = next.roi.h;
  plan.dwell_ns = next.dwell_ns;
  plan.enabled = enabled ? 1 : 0;
  plans_[target].publish(plan);
}

rt::Status Pipeline::start(bool strict) {
  auto thread_config = [&](const char* name, const config::StageThreadConfig& s) {
    rt::RtThreadConfig c;
    c.name = name;
    c.cpu = s.cpu;
    c.priority = s.priority;
    c.strict = strict;
    return c;
  };
  rt::Status st = acquisition_thread_.start(thread_config("sp-acquire", config_.acquisition),
                                            [this] { acquisition_loop(); });
  if (!st) return st;
  st = correlation_thread_.start(thread_config("sp-correlate", config_.correlation),
                                 [this] { correlation_loop(); });
  if (!st) {
    request_stop();
    join();
    return st;
  }
  if (!config_.output_on_correlation_thread) {
    st = output_thread_.start(thread_config("sp-output", config_.output), [this] { output_loop(); });
    if (!st) {
      request_stop();
      join();
      return st;
    }
  }
  return rt::Status::success();
}

void Pipeline::join() {
  if (acquisition_thread_.joinable()) acquisition_thread_.join();
  if (correlation_thread_.joinable()) correlation_thread_.join();
  if (output_thread_.joinable()) output_thread_.join();
}

std::vector<std::string> Pipeline::placements() const {
  std::vector<std::string> out;
  out.push_back("acquisition: " + acquisition_thread_.placement());
  out.push_back("correlation: " + correlation_thread_.placement());
  out.push_back(config_.output_on_correlation_thread ? "output: on the correlation thread"
                                                     : "output: " + output_thread_.placement());
  return out;
}

std::vector<std::string> Pipeline::warnings() const {
  std::vector<std::string> out;
  for (const rt::RtThread* t : {&acquisition_thread_, &correlation_thread_, &output_thread_}) {
    if (!t->warning().empty()) out.push_back(t->warning());
  }
  return out;
}

std::size_t Pipeline::frame_pool_slots_for(const config::PipelineConfig& pipeline) noexcept {
  const std::size_t ring = std::clamp<std::uint32_t>(pipeline.frame_ring, 2, kFrameRingCapacity);
  return std::clamp<std::size_t>(pipeline.frame_pool_slots, ring + 3, kFreeRingCapacity);
}

std::uint64_t Pipeline::frame_pool_bytes_for(const config::PipelineConfig& pipeline,
                                             const hal::ScanLimits& limits) noexcept {
  return static_cast<std::uint64_t>(frame_pool_slots_for(pipeline)) * frame_slot_pixels(limits) *
         sizeof(hal::Pixel);
}

std::size_t Pipeline::frame_pool_bytes() const noexcept {
  return pool_.size() * pool_.capacity_pixels() * sizeof(hal::Pixel);
}

}  // namespace sempose::pipeline
