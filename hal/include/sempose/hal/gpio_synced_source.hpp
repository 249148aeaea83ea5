// A ScanSource decorator: a frame is done only when the wrapped source says so AND the scan
// generator's frame-sync edge has arrived (the edge is the "interrupt"). wait_fd() is the
// edge fd, so acquisition can poll(2) it instead of timing the scan itself.
//
// Edge bookkeeping (all counted, readable from any thread):
//   edges     every rising edge read
//   missed    the inner scan finished but no edge came within timeout_ns: the frame is
//             completed anyway, flagged FrameStatus::kBad
//   late      the first edge after a missed one (it belonged to the previous frame)
//   spurious  edges while no scan was pending, or extra edges during one scan
// With adopt_edge_time (an inner source on CLOCK_MONOTONIC, like the edge) the frame's
// t_scan_end_ns becomes the edge's kernel timestamp when that is later than the inner
// source's own; a virtual-time inner source keeps its own clock.
#pragma once

#include <atomic>
#include <cstdint>

#include "sempose/hal/gpio_frame_sync.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::hal {

struct FrameSyncCounters {
  std::atomic<std::uint64_t> edges{0};
  std::atomic<std::uint64_t> missed{0};
  std::atomic<std::uint64_t> late{0};
  std::atomic<std::uint64_t> spurious{0};
};

class GpioSyncedSource final : public ScanSource {
 public:
  GpioSyncedSource(ScanSource& inner, EdgeSource& edges, std::int64_t timeout_ns, bool adopt_edge_time = true) noexcept
      : inner_(inner), edges_(edges), timeout_ns_(timeout_ns), adopt_edge_time_(adopt_edge_time) {}

  const ScanLimits& limits() const noexcept override { return inner_.limits(); }
  StartResult start(const ScanRequest& req, FrameSlot& slot) noexcept override;
  PollResult poll() noexcept override;
  std::int64_t now_ns() const noexcept override { return inner_.now_ns(); }
  std::int64_t expected_done_ns() const noexcept override { return inner_.expected_done_ns(); }
  int wait_fd() const noexcept override { return edges_.fd(); }

  const FrameSyncCounters& counters() const noexcept { return counters_; }

 private:
  // Reads pending edges; returns how many; remembers the first one's timestamp.
  int take_edges() noexcept;
  static void bump(std::atomic<std::uint64_t>& c, std::uint64_t n = 1) noexcept {
    rt::add_single_writer(c, n);
  }

  ScanSource& inner_;
  EdgeSource& edges_;
  std::int64_t timeout_ns_;
  bool adopt_edge_time_;
  FrameSlot* slot_ = nullptr;
  bool pending_ = false;       // a scan was started and not yet reported done
  bool inner_done_ = false;
  bool edge_seen_ = false;
  bool expect_late_ = false;   // the previous frame timed out: its edge may still come
  std::int64_t edge_ns_ = 0;
  std::int64_t inner_done_ns_ = 0;
  FrameSyncCounters counters_;
};

}  // namespace sempose::hal
