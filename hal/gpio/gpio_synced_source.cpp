// Frame-sync decorator for a scan source. See gpio_synced_source.hpp.
#include "sempose/hal/gpio_synced_source.hpp"

namespace sempose::hal {

int GpioSyncedSource::take_edges() noexcept {
  std::int64_t ts[16];
  int total = 0;
  for (;;) {
    const int n = edges_.read_edges(ts, 16);
    if (n <= 0) break;
    total += n;
    bump(counters_.edges, static_cast<std::uint64_t>(n));
    for (int i = 0; i < n; ++i) {
      if (expect_late_) {  // belongs to the frame we already completed as "missed"
        expect_late_ = false;
        bump(counters_.late);
      } else if (pending_ && !edge_seen_) {
        edge_seen_ = true;
        edge_ns_ = ts[i];
      } else {
        bump(counters_.spurious);
      }
    }
    if (n < 16) break;
  }
  return total;
}

StartResult GpioSyncedSource::start(const ScanRequest& req, FrameSlot& slot) noexcept {
  if (pending_) return StartResult::kBusy;
  take_edges();  // edges from before this scan are not its "done"
  const StartResult r = inner_.start(req, slot);
  if (r != StartResult::kStarted) return r;
  slot_ = &slot;
  pending_ = true;
  inner_done_ = false;
  edge_seen_ = false;
  edge_ns_ = 0;
  const std::int64_t expected = inner_.expected_done_ns();
  inner_done_ns_ = expected > 0 ? expected : inner_.now_ns();  // deadline base: the scan's expected end
  return r;
}

PollResult GpioSyncedSource::poll() noexcept {
  if (!pending_) {
    take_edges();
    return inner_.poll();
  }
  take_edges();
  if (!inner_done_) {
    const PollResult r = inner_.poll();
    if (r == PollResult::kError) {
      pending_ = false;
      return r;
    }
    if (r != PollResult::kDone) return r;
    inner_done_ = true;
  }
  if (edge_seen_) {
    if (adopt_edge_time_ && edge_ns_ > slot_->meta.t_scan_end_ns) slot_->meta.t_scan_end_ns = edge_ns_;
    pending_ = false;
    return PollResult::kDone;
  }
  if (inner_.now_ns() >= inner_done_ns_ + timeout_ns_) {
    bump(counters_.missed);
    slot_->meta.status = FrameStatus::kBad;
    expect_late_ = true;
    pending_ = false;
    return PollResult::kDone;
  }
  return PollResult::kBusy;
}

}  // namespace sempose::hal
