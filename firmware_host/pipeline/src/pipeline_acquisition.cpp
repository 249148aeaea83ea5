// The acquisition stage (pipeline.hpp): polls the scan source ISR-like, hands finished frames
// to correlation, starts each target's next planned scan.
#include <poll.h>

#include <algorithm>

#include "cpu_relax.hpp"
#include "sempose/pipeline/pipeline.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {

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
    m.t_seen_ns = clock_.seen_ns(m.t_scan_end_ns);
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
      if (sleep_polling_) {
        const std::int64_t due = source_.expected_done_ns();
        if (due - slack_ns > rt::now_ns()) rt::sleep_until_ns(due - slack_ns);
      }
      const hal::PollResult r = source_.poll();
      if (r == hal::PollResult::kDone || r == hal::PollResult::kError) {
        finish(scanning, r == hal::PollResult::kDone);
        scanning = kNone;
        ++scanned;
      } else if (r == hal::PollResult::kBusy) {
        if (sleep_polling_ && sync_fd >= 0) {
          // ISR-like: sleep in the kernel until the scan generator's frame-done edge (or
          // 1 ms, so the source can time out a missed edge), instead of polling on a timer.
          pollfd pfd{sync_fd, POLLIN, 0};
          const timespec timeout{0, 1'000'000};
          ppoll(&pfd, 1, &timeout, nullptr);
        } else if (sleep_polling_ && rt::now_ns() > source_.expected_done_ns() + 2 * slack_ns) {
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

    // Lock step (virtual time): start the next scan only once correlation took every frame,
    // so a test run is the same sequence of frames on any machine. The whole idle sleep, not
    // the shortest: with both stages on one core (the default placement) this thread, the
    // higher priority, waking every few µs left correlation ~1 % of the core — one pose in 5 s.
    if (clock_.lock_step() && (waiting != kNone || frames_taken_.load(std::memory_order_acquire) !=
                                                  frames_handed_.load(std::memory_order_relaxed))) {
      idle_wait(whole_idle_sleep());
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
      idle_wait(whole_idle_sleep());
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
      idle_wait(whole_idle_sleep());  // correlation holds every slot: let it run
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
      idle_wait(whole_idle_sleep());  // a failing source is retried, not spun on
    }
  }
  // Drain: the last finished frame still goes to correlation.
  while (waiting != kNone && !hand_on(waiting)) idle_wait(whole_idle_sleep());
  counters_.acquisition_allocs.set(rt::alloc::this_thread_allocations() - allocs_at_start);
  acquisition_done_.store(true, std::memory_order_release);
}

}  // namespace sempose::pipeline
