// Replay of a recorded sequence (README: Replay and recording) as a ScanSource: every start() serves the
// requested ROI as a crop of the current full-field frame and advances one frame; at the end
// start() returns kEnded, or wraps around when loop is set.
// All frames are loaded at setup (the loop does no I/O); the constructor refuses sequences
// larger than half the machine's physical memory. The field size and bits come from the
// frames (all must share one size). Timestamps: with frames.csv (frame,t_ns) a scan starts at
// max(virtual now, t_ns of the frame); without it, at the virtual now (scan-time model).
// With ground_truth.csv (frame,x_px,y_px,phi_deg[,target]) the truth is filled in.
// clock "real" instead paces poll() on CLOCK_MONOTONIC like the live simulator.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "sempose/config/sim_config.hpp"
#include "sempose/hal/image.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/hal/scan_timer.hpp"

namespace sempose::hal {

class ReplaySource final : public TimedScanSource {
 public:
  // Setup: throws std::runtime_error naming the directory/file and the problem.
  ReplaySource(const ScanLimits& limits, const config::ReplayConfig& cfg);

  const ScanLimits& limits() const noexcept override { return limits_; }
  StartResult start(const ScanRequest& req, FrameSlot& slot) noexcept override;

  std::size_t frame_count() const noexcept { return frames_.size(); }
  std::size_t next_frame() const noexcept { return index_; }

 private:
  ScanLimits limits_;
  bool loop_;
  std::vector<Image> frames_;
  std::vector<std::uint8_t> repeats_;  // per frame: 1 when it repeats the one before (a bad frame)
  std::string first_repeat_;
  std::vector<std::int64_t> t_ns_;  // per frame, or empty
  std::vector<std::array<TargetTruth, kMaxTargets>> truth_;  // per frame, or empty
  std::uint8_t truth_count_ = 0;
  std::int64_t loop_offset_ns_ = 0;
  std::size_t index_ = 0;
  std::uint64_t seq_ = 0;
};

// Sorted *.pgm names in a directory (setup; throws when it is missing or has none). The
// extension in any case (.pgm, .PGM, .Pgm: a recording copied through a tool that changed the
// case): a frame named .PGM used to be skipped without a word (frames.csv then had "one row
// too many", or without frames.csv the recording was a frame short). A FIFO, device or socket
// named *.pgm is refused by name (reading it would block or never end); a directory is not a
// frame and is passed over. Frames all named frame_N.pgm must be numbered without a gap (a
// missing one is named); other names are taken in name order as they are.
std::vector<std::string> list_pgm_frames(const std::string& dir);
// Whether a file name ends in .pgm, in any case.
bool is_pgm_name(const std::string& path);

}  // namespace sempose::hal
