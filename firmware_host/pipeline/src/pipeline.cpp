#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pipeline/pose_input.hpp"

#include <poll.h>

#include <algorithm>
#include <stdexcept>

#include "sempose/pose/tracker.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {
namespace {

inline void cpu_relax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield" ::: "memory");
#else
  asm volatile("" ::: "memory");
#endif
}

std::size_t slot_pixels(const hal::ScanLimits& l) {
  // A slot must hold the full field: the start search scans it.
  const auto field = static_cast<std::size_t>(l.field_w) * static_cast<std::size_t>(l.field_h);
  const auto roi = static_cast<std::size_t>(l.max_roi_w) * static_cast<std::size_t>(l.max_roi_h);
  return std::max(field, roi);
}

}  // namespace

Pipeline::Pipeline(const config::PipelineConfig& pipeline, const config::GovernorConfig& governor,
                   hal::ScanSource& source, std::vector<pose::Tracker*> trackers, PoseSink& sink)
    : config_(pipeline),
      source_(source),
      trackers_(std::move(trackers)),
      sink_(sink),
      governor_(governor, source.limits(), std::max<int>(1, static_cast<int>(trackers_.size()))),
      acquire_dwell_ns_(0),
      virtual_time_(source.is_virtual_time()),
      spin_(pipeline.polling == "spin"),
      frame_ring_depth_(std::clamp<std::uint32_t>(pipeline.frame_ring, 2, kFrameRingCapacity)),
      pose_ring_depth_(std::clamp<std::uint32_t>(pipeline.pose_ring, 2, kPoseRingCapacity)),
      pool_(std::clamp<std::size_t>(pipeline.frame_pool_slots, frame_ring_depth_ + 3, kFreeRingCapacity),
            slot_pixels(source.limits())) {
  if (trackers_.empty() || trackers_.size() > static_cast<std::size_t>(hal::kMaxTargets)) {
    throw std::invalid_argument("pipeline: 1 to " + std::to_string(hal::kMaxTargets) +
                                " targets are supported, got " + std::to_string(trackers_.size()));
  }
  for (auto* t : trackers_) {
    if (t == nullptr) throw std::invalid_argument("pipeline: a target has no tracker");
  }
  // The dwell of full-field (start search) scans: the governor's initial dwell, quantized.
  acquire_dwell_ns_ = governor_.initial_dwell_ns();
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
  if (spin_ && !virtual_time_) {
    for (int i = 0; i < 64; ++i) cpu_relax();
    return;
  }
  const std::int64_t t = rt::now_ns();
  const std::int64_t latest = t + static_cast<std::int64_t>(config_.idle_sleep_us) * rt::kNsPerUs;
  const std::int64_t earliest = t + 5 * rt::kNsPerUs;
  rt::sleep_until_ns(std::clamp(until_ns, earliest, latest));
}

void Pipeline::publish_plan(std::uint8_t target, bool enabled) noexcept {
  const hal::Roi roi = trackers_[target]->next_roi();
  const hal::ScanLimits& l = source_.limits();
  const bool full_field = l.is_full_field(roi.x, roi.y, roi.w, roi.h);
  ScanPlan plan{};
  plan.x = roi.x;
  plan.y = roi.y;
  plan.w = roi.w;
  plan.h = roi.h;
  plan.dwell_ns = full_field ? acquire_dwell_ns_ : governor_.next_dwell_ns(target, roi.w, roi.h);
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

std::size_t Pipeline::frame_pool_bytes() const noexcept {
  return pool_.size() * pool_.capacity_pixels() * sizeof(hal::Pixel);
}

// ---------------------------------------------------------------- acquisition

void Pipeline::acquisition_loop() noexcept {
  const std::uint64_t allocs_at_start = rt::alloc::this_thread_allocations();
  std::array<hal::FramePool::Index, kFreeRingCapacity> free_stack{};
  std::size_t free_count = 0;
  constexpr hal::FramePool::Index kNone = 0xFFFF;
  hal::FramePool::Index scanning = kNone;   // slot being scanned
  hal::FramePool::Index waiting = kNone;    // finished, not yet in the ring (ring was full)
  std::size_t schedule_pos = 0;
  std::uint64_t scanned = 0;
  const std::int64_t slack_ns = static_cast<std::int64_t>(config_.poll_slack_us) * rt::kNsPerUs;
  const int sync_fd = source_.wait_fd();  // a frame-done edge (GPIO), or -1

  auto collect_free = [&]() noexcept {
    hal::FramePool::Index i = 0;
    while (free_stack.size() > free_count && free_slots_.try_pop(i)) free_stack[free_count++] = i;
  };
  auto hand_on = [&](hal::FramePool::Index i) noexcept {
    if (frames_.size() >= frame_ring_depth_) return false;
    pool_.transfer(i, kAcq, kCorr);
    if (!frames_.try_push(i)) {
      pool_.transfer(i, kCorr, kAcq);
      return false;
    }
    frames_handed_.store(frames_handed_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
    return true;
  };
  auto finish = [&](hal::FramePool::Index i, bool ok) noexcept {
    hal::FrameMeta& m = pool_[i].meta;
    m.t_seen_ns = virtual_time_ ? m.t_scan_end_ns : rt::now_ns();
    if (!ok) m.status = hal::FrameStatus::kBad;
    histograms_.poll_lag.record_ns(m.t_seen_ns - m.t_scan_end_ns);
    histograms_.scan_time.record_ns(m.t_scan_end_ns - m.t_scan_start_ns);
    histograms_.dwell_ns.record_ns(static_cast<std::int64_t>(m.dwell_ns) * rt::kNsPerUs);
    counters_.frames_scanned.add();
    if (!ok) counters_.scan_errors.add();
    if (waiting != kNone) {  // the ring was full: the older finished frame goes
      free_stack[free_count++] = waiting;
      counters_.dropped_acquisition.add();
    }
    waiting = i;
    if (hand_on(waiting)) waiting = kNone;
  };

  for (;;) {
    collect_free();
    if (waiting != kNone && hand_on(waiting)) waiting = kNone;

    if (scanning != kNone) {
      if (!virtual_time_ && !spin_) {
        const std::int64_t due = source_.expected_done_ns();
        if (due - slack_ns > rt::now_ns()) rt::sleep_until_ns(due - slack_ns);
      }
      const hal::PollResult r = source_.poll();
      if (r == hal::PollResult::kDone || r == hal::PollResult::kError) {
        finish(scanning, r == hal::PollResult::kDone);
        scanning = kNone;
        ++scanned;
      } else if (r == hal::PollResult::kBusy) {
        if (!virtual_time_ && !spin_ && sync_fd >= 0) {
          // ISR-like: sleep in the kernel until the scan generator's frame-done edge (or
          // 1 ms, so the source can time out a missed edge), instead of polling on a timer.
          pollfd pfd{sync_fd, POLLIN, 0};
          const timespec timeout{0, 1'000'000};
          ppoll(&pfd, 1, &timeout, nullptr);
        } else if (!virtual_time_ && !spin_ && rt::now_ns() > source_.expected_done_ns() + 2 * slack_ns) {
          rt::sleep_until_ns(rt::now_ns() + 10 * rt::kNsPerUs);  // late source: do not hog a shared core
        } else {
          cpu_relax();
        }
        continue;
      } else {
        scanning = kNone;  // idle: the source lost the scan; the slot is ours again
        counters_.scan_errors.add();
      }
    }

    const bool stop = stop_requested_.load(std::memory_order_acquire) ||
                      (stop_after_frames_ != 0 && scanned >= stop_after_frames_);
    if (stop) break;

    // Virtual time: start the next scan only once correlation took every frame, so a test
    // run is the same sequence of frames on any machine.
    if (virtual_time_ && (waiting != kNone || frames_taken_.load(std::memory_order_acquire) !=
                                                  frames_handed_.load(std::memory_order_relaxed))) {
      idle_wait(0);
      continue;
    }

    // Next target in the schedule whose plan is enabled. A full-field plan is scanned once
    // per version: while its start search runs, scanning the field again (~200 ms of beam
    // time) would only deliver a frame the new plan has already made stale.
    ScanPlan plan{};
    std::uint8_t target = 0;
    bool found = false;
    for (std::size_t k = 0; k < schedule_len_ && !found; ++k) {
      target = schedule_[schedule_pos];
      schedule_pos = (schedule_pos + 1) % schedule_len_;
      const std::uint32_t version = plans_[target].version();
      plan = plans_[target].read();
      const bool full_field = source_.limits().is_full_field(plan.x, plan.y, plan.w, plan.h);
      found = plan.enabled != 0 && !(full_field && full_field_version_[target] == version);
      if (found && full_field) full_field_version_[target] = version;
    }
    if (!found) {
      idle_wait(rt::now_ns() + static_cast<std::int64_t>(config_.idle_sleep_us) * rt::kNsPerUs);
      continue;
    }
    hal::FramePool::Index slot = kNone;
    if (free_count > 0) {
      slot = free_stack[--free_count];
    } else if (waiting != kNone) {  // no free slot: the waiting (oldest finished) frame goes
      slot = waiting;
      waiting = kNone;
      counters_.dropped_acquisition.add();
      counters_.no_free_slot.add();
    } else {
      idle_wait(0);
      continue;
    }
    hal::ScanRequest req;
    req.roi = hal::Roi{plan.x, plan.y, plan.w, plan.h};
    req.dwell_ns = plan.dwell_ns;
    req.target = target;
    // The arming cost is wall-clock CPU time even on the virtual clock (rendering, ioctls).
    const std::int64_t t_arm = rt::now_ns();
    const hal::StartResult sr = source_.start(req, pool_[slot]);
    if (sr == hal::StartResult::kStarted) histograms_.arm.record_ns(rt::now_ns() - t_arm);
    if (sr == hal::StartResult::kStarted) {
      scanning = slot;
      const std::uint64_t lo = counters_.dwell_min_ns.get();
      if (lo == 0 || plan.dwell_ns < lo) counters_.dwell_min_ns.set(plan.dwell_ns);
      if (plan.dwell_ns > counters_.dwell_max_ns.get()) counters_.dwell_max_ns.set(plan.dwell_ns);
      next_frame_expected_ns_.store(source_.expected_done_ns(), std::memory_order_relaxed);
    } else {
      free_stack[free_count++] = slot;
      if (sr == hal::StartResult::kEnded) {
        source_ended_.store(true, std::memory_order_release);
        break;
      }
      counters_.scan_errors.add();
      idle_wait(0);
    }
  }
  // Drain: the last finished frame still goes to correlation.
  while (waiting != kNone && !hand_on(waiting)) idle_wait(0);
  counters_.acquisition_allocs.set(rt::alloc::this_thread_allocations() - allocs_at_start);
  acquisition_done_.store(true, std::memory_order_release);
}

// ---------------------------------------------------------------- correlation

bool Pipeline::apply_command(const Command& c) noexcept {
  const std::size_t n = trackers_.size();
  // A command naming something that does not exist is refused as a whole (and not
  // acknowledged): a controller must not believe a magnification step or target changed.
  const bool target_ok = c.target == 0xFF || c.target < n;
  bool ok = target_ok;
  if (ok && c.kind == CommandKind::kSelectPatternSet) {
    for (std::size_t t = 0; t < n; ++t) {
      if ((c.target == 0xFF || c.target == t) && c.arg >= trackers_[t]->pattern_set_count()) ok = false;
    }
  }
  StatusWords st = status_.read();
  if (!ok) {
    counters_.commands_rejected.add();
    st.commands_rejected = static_cast<std::uint32_t>(counters_.commands_rejected.get());
    status_.publish(st);
    return false;
  }
  auto for_targets = [&](auto&& fn) {
    for (std::size_t t = 0; t < n; ++t) {
      if (c.target == 0xFF || c.target == t) fn(static_cast<std::uint8_t>(t));
    }
  };
  switch (c.kind) {
    case CommandKind::kSelectPatternSet:
      // A non-zero scale from the controller overrides the configured nm/px of the set
      // (e.g. a magnification step calibrated on the microscope); 0 keeps the configured one.
      for_targets([&](std::uint8_t t) {
        if (trackers_[t]->select_pattern_set(c.arg)) nm_per_px_override_[t] = c.nm_per_px > 0 ? c.nm_per_px : 0;
      });
      break;
    case CommandKind::kStart:
      running_ = true;
      break;
    case CommandKind::kStop:
      running_ = false;
      break;
    case CommandKind::kReacquire:
      for_targets([&](std::uint8_t t) { trackers_[t]->request_reacquire(); });
      break;
  }
  for (std::size_t t = 0; t < n; ++t) publish_plan(static_cast<std::uint8_t>(t), running_);
  st.running = running_ ? 1 : 0;
  st.last_command_seq = c.seq;
  status_.publish(st);
  counters_.commands.add();
  return true;
}

void Pipeline::correlate(hal::FramePool::Index slot) noexcept {
  hal::FrameSlot& s = pool_[slot];
  hal::FrameMeta& m = s.meta;
  const std::uint8_t target = m.target < trackers_.size() ? m.target : 0;
  pose::Tracker& tracker = *trackers_[target];

  const std::int64_t t_start = virtual_time_ ? std::max(m.t_seen_ns, prev_pose_done_ns_) : rt::now_ns();
  const std::int64_t wall0 = rt::now_ns();
  const pose::PoseEstimate est = tracker.update(to_pose_frame(m, s.pixels));
  const std::int64_t wall1 = rt::now_ns();
  std::int64_t compute_ns = wall1 - wall0;
  if (virtual_time_ && config_.virtual_compute_ns != 0) compute_ns = config_.virtual_compute_ns;
  m.t_pose_done_ns = virtual_time_ ? t_start + compute_ns : wall1;

  // The frame waited for the tracker: a deadline overrun (not counted after a start search,
  // which is long by design).
  if (prev_pose_done_ns_ != 0 && m.t_scan_end_ns < prev_pose_done_ns_ && !prev_pose_was_search_) {
    counters_.overruns.add();
  }
  prev_pose_done_ns_ = m.t_pose_done_ns;
  prev_pose_was_search_ = est.searched;
  histograms_.queue.record_ns(t_start - m.t_seen_ns);
  histograms_.compute.record_ns(compute_ns);

  const bool tracking = est.state == pose::TrackState::kTracking;
  governor_.observe(target, compute_ns, est.score, est.psr, tracking && !est.searched);
  publish_plan(target, running_);
  last_state_[target] = est.state;
  {
    StatusWords st = status_.read();  // keeps the command acknowledgement fields
    pose::TrackState worst = pose::TrackState::kTracking;
    for (std::size_t t = 0; t < trackers_.size(); ++t) {
      if (static_cast<int>(last_state_[t]) > static_cast<int>(worst)) worst = last_state_[t];
    }
    st.state = static_cast<std::uint8_t>(worst);
    st.pattern_set = est.pattern_set;
    st.running = running_ ? 1 : 0;
    st.dwell_ns = m.dwell_ns;
    status_.publish(st);
  }

  TargetCounters& tc = counters_.targets[target];
  tc.poses.add();
  if (tracking) tc.tracked.add();
  if (est.searched) tc.searches.add();

  PoseRecord p;
  p.frame_seq = m.seq;
  p.pose_seq = pose_seq_[target]++;
  p.target = target;
  p.pattern_set = est.pattern_set;
  p.state = est.state;
  p.reason_bits = est.reason_bits;
  p.x_px = est.x_px;
  p.y_px = est.y_px;
  p.phi_deg = est.phi_deg;
  p.score = est.score;
  p.psr = est.psr;
  p.target_scale = est.scale;
  p.dwell_ns = m.dwell_ns;
  p.nm_per_px = nm_per_px_override_[target] > 0 ? nm_per_px_override_[target] : tracker.nm_per_px();
  p.t_scan_end_ns = m.t_scan_end_ns;
  p.t_pose_done_ns = m.t_pose_done_ns;
  if (target < m.truth_count && m.truth[target].present) {
    p.truth_present = true;
    p.truth_x_px = m.truth[target].x_px;
    p.truth_y_px = m.truth[target].y_px;
    p.truth_phi_deg = m.truth[target].phi_deg;
  }
  if (poses_.size() >= pose_ring_depth_ || !poses_.try_push(p)) counters_.poses_ring_full.add();
}

void Pipeline::correlation_loop() noexcept {
  const std::uint64_t allocs_at_start = rt::alloc::this_thread_allocations();
  const bool run_output = config_.output_on_correlation_thread;
  const std::int64_t slack_ns = static_cast<std::int64_t>(config_.poll_slack_us) * rt::kNsPerUs;
  for (;;) {
    Command c;
    while (commands_.try_pop(c)) apply_command(c);

    // Drain to the newest frame: older ones are stale by now (dropped, counted).
    hal::FramePool::Index newest = 0;
    bool have = false;
    hal::FramePool::Index i = 0;
    std::uint64_t taken = 0;
    while (frames_.try_pop(i)) {
      ++taken;
      if (have) {
        pool_.transfer(newest, kCorr, kAcq);
        free_slots_.try_push(newest);
        counters_.dropped_correlation.add();
      }
      newest = i;
      have = true;
    }
    if (have) {
      correlate(newest);
      pool_.transfer(newest, kCorr, kAcq);
      free_slots_.try_push(newest);
      // Virtual pacing: count the frame as taken only once its pose exists.
      frames_taken_.store(frames_taken_.load(std::memory_order_relaxed) + taken, std::memory_order_release);
      if (run_output) output_step();
      continue;
    }
    if (run_output && output_step()) continue;
    if (acquisition_done_.load(std::memory_order_acquire) && frames_.empty()) break;
    // Wait for the frame due next. While the non-RT watchdog reports a stall, poll every
    // idle_sleep_us instead of every 5 us, so this FIFO thread does not starve the non-RT
    // thread on its core, which must still answer SIGTERM. (Backing off on lateness alone,
    // > 1 ms or > 50 ms overdue, changed which frame a REACQUIRE met in the VM test.)
    const std::int64_t due = next_frame_expected_ns_.load(std::memory_order_relaxed) + slack_ns;
    idle_wait((faults_.load(std::memory_order_relaxed) & kFaultStageStalled) != 0
                  ? rt::now_ns() + static_cast<std::int64_t>(config_.idle_sleep_us) * rt::kNsPerUs
                  : due);
  }
  if (run_output) {
    while (output_step()) {
    }
  }
  counters_.correlation_allocs.set(rt::alloc::this_thread_allocations() - allocs_at_start);
  correlation_done_.store(true, std::memory_order_release);
  if (run_output) output_done_.store(true, std::memory_order_release);
}

// ---------------------------------------------------------------- output

bool Pipeline::output_step() noexcept {
  bool worked = false;
  PoseRecord p;
  while (poses_.try_pop(p)) {
    worked = true;
    const std::int64_t t_sent = virtual_time_ ? p.t_pose_done_ns : rt::now_ns();
    const PublishResult r = sink_.publish(p, t_sent);
    if (r == PublishResult::kSent) {
      counters_.sent.add();
    } else if (r == PublishResult::kDropped) {
      counters_.publish_dropped.add();
    } else {
      counters_.publish_errors.add();
    }
    histograms_.output.record_ns(t_sent - p.t_pose_done_ns);
    histograms_.end_to_end.record_ns(t_sent - p.t_scan_end_ns);
  }
  const StatusWords words = status_.read();
  PipelineStatus status;
  status.state = static_cast<pose::TrackState>(words.state);
  status.pattern_set = words.pattern_set;
  status.running = words.running != 0;
  status.dwell_ns = words.dwell_ns;
  status.dropped_frames = static_cast<std::uint32_t>(dropped_frames());
  status.overruns = static_cast<std::uint32_t>(counters_.overruns.get());
  status.last_command_seq = words.last_command_seq;
  status.commands_rejected = words.commands_rejected;
  status.fault_bits = faults_.load(std::memory_order_relaxed);
  // A stalled source produces no poses: the last pose's TRACKING must not stand for "valid".
  if (status.fault_bits & (kFaultSourceStalled | kFaultStageStalled)) status.state = pose::TrackState::kLost;
  if (virtual_time_) {
    if (worked) last_virtual_now_ns_ = p.t_pose_done_ns;
    sink_.service(status, last_virtual_now_ns_);
  } else {
    sink_.service(status, rt::now_ns());
  }
  Command c;
  // Only take a command when there is room for it: the sink keeps the rest.
  while (commands_.size() < kCommandRingCapacity && sink_.next_command(c)) {
    worked = true;
    commands_.try_push(c);
  }
  return worked;
}

void Pipeline::output_loop() noexcept {
  const std::uint64_t allocs_at_start = rt::alloc::this_thread_allocations();
  for (;;) {
    if (output_step()) continue;
    if (correlation_done_.load(std::memory_order_acquire) && poses_.empty()) break;
    idle_wait(rt::now_ns() + static_cast<std::int64_t>(config_.idle_sleep_us) * rt::kNsPerUs);
  }
  counters_.output_allocs.set(rt::alloc::this_thread_allocations() - allocs_at_start);
  output_done_.store(true, std::memory_order_release);
}

}  // namespace sempose::pipeline
