// A ROI frame as it travels through the pipeline: metadata + pixels in a frame-pool slot.
#pragma once

#include <cstdint>

#include "sempose/config/scan_config.hpp"
#include "sempose/rt/frame_pool.hpp"

namespace sempose::hal {

inline constexpr int kMaxTargets = 4;

// A rectangle of the scan field (one definition, in config, shared with the pose engine).
using Roi = config::Roi;

// Where a simulated target really was during the scan (the README's conventions).
struct TargetTruth {
  double x_px = 0;
  double y_px = 0;
  double phi_deg = 0;
  bool present = false;  // false: the target is outside the field / not in the scene
  double scale = 1.0;    // size relative to the configured one (simulated scale trajectories)
};

enum class FrameStatus : std::uint8_t {
  kOk = 0,
  kBad = 1,  // the source flagged the frame (overrun, truncated DMA, missed sync edge)
};

struct FrameMeta {
  std::uint64_t seq = 0;          // per source, +1 per completed scan
  Roi roi;                        // what was scanned; pixels are roi.w x roi.h, row-major
  std::int32_t field_w = 0;       // full scan field
  std::int32_t field_h = 0;
  std::uint32_t dwell_ns = 0;     // pixel dwell of this scan
  std::uint8_t bits = 8;          // significant bits per pixel (8 or 16)
  std::uint8_t target = 0;        // index of the target this ROI was scanned for
  std::uint8_t truth_count = 0;   // simulated sources only
  FrameStatus status = FrameStatus::kOk;
  // CLOCK_MONOTONIC ns (or the source's virtual clock). 0 = not reached yet.
  std::int64_t t_scan_start_ns = 0;
  std::int64_t t_scan_end_ns = 0;  // the "interrupt"
  std::int64_t t_seen_ns = 0;      // acquisition's poll saw it
  std::int64_t t_pose_done_ns = 0;  // the send time is the output stage's (PoseSink::publish)
  TargetTruth truth[kMaxTargets];
};

using Pixel = std::uint16_t;
using FramePool = rt::FramePool<FrameMeta, Pixel>;
using FrameSlot = FramePool::Slot;

}  // namespace sempose::hal
