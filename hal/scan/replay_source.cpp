#include "sempose/hal/replay_source.hpp"
#include "sempose/rt/memory_room.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "sempose/hal/frames_csv.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/scan_request_check.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::hal {

namespace {
// A looped recording's span at most (52 days): a clock can go on ~1000 passes of it after the
// largest stamp frames.csv accepts (2^62), with room for a scan after each.
constexpr std::int64_t kMaxLoopSpanNs = std::int64_t{1} << 52;
}  // namespace

namespace fs = std::filesystem;

bool is_pgm_name(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  return ext.size() == 4 && ext[0] == '.' && (ext[1] | 0x20) == 'p' && (ext[2] | 0x20) == 'g' && (ext[3] | 0x20) == 'm';
}

std::vector<std::string> list_pgm_frames(const std::string& dir) {
  std::error_code ec;
  if (dir.empty() || !fs::is_directory(dir, ec)) {
    throw std::runtime_error(dir + ": not a directory of recorded frames (missing?)");
  }
  std::vector<std::string> names;
  // Unreadable (no read or search permission): said as the other faults are, not the library's
  // "filesystem error: directory iterator cannot open directory" (found probing).
  fs::directory_iterator it(dir, ec);
  if (ec) throw std::runtime_error(dir + ": the recording's folder cannot be read: " + ec.message());
  for (const auto& e : it) {
    if (!is_pgm_name(e.path().string())) continue;
    std::error_code kind_ec;
    if (e.is_regular_file(kind_ec)) {
      names.push_back(e.path().string());
    } else if (!e.is_directory(kind_ec)) {
      const fs::file_status st = e.status(kind_ec);
      const char* kind = st.type() == fs::file_type::fifo        ? "a FIFO"
                         : st.type() == fs::file_type::character ? "a character device"
                         : st.type() == fs::file_type::block     ? "a block device"
                         : st.type() == fs::file_type::socket    ? "a socket"
                         : st.type() == fs::file_type::not_found ? "a dangling link"
                                                                 : "not a regular file";
      throw std::runtime_error(e.path().string() + ": named like a frame but " + kind + ", not a PGM file");
    }
  }
  if (names.empty()) throw std::runtime_error(dir + ": no *.pgm frames in the directory");
  std::sort(names.begin(), names.end());
  // Frames are taken in name order; named frame_N.pgm (as sim and recorders write them), a number
  // missing between two frames shifts every later frame's time and truth by one (found probing:
  // frame_000010.pgm deleted, the truth compared against the wrong frames without a word).
  const auto number_of = [](const std::string& path, long long& n) {
    const std::string stem = fs::path(path).stem().string();
    if (stem.rfind("frame_", 0) != 0 || stem.size() == 6 || stem.size() > 24) return false;
    n = 0;
    for (std::size_t i = 6; i < stem.size(); ++i) {
      if (stem[i] < '0' || stem[i] > '9') return false;
      n = n * 10 + (stem[i] - '0');
    }
    return true;
  };
  long long prev = 0, n = 0;
  // A folder of frame_N.pgm files with another PGM among them (img_0001.pgm, frame_-1.pgm,
  // "frame_000012 .pgm") replayed that one as one more frame, unsaid (found probing).
  std::size_t numbered_count = 0, odd = names.size();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (number_of(names[i], n)) ++numbered_count;
    else if (odd == names.size()) odd = i;
  }
  if (numbered_count > 0 && odd < names.size()) {
    throw std::runtime_error(names[odd] + ": not named frame_N.pgm like the " + std::to_string(numbered_count) +
                             " other frames of " + dir + ": it would be replayed as one more frame; move it out");
  }
  const bool numbered = numbered_count == names.size();
  for (std::size_t i = 0; numbered && i < names.size(); ++i) {
    number_of(names[i], n);
    // The poses' frame column, frames.csv's rows and a truth's frames count from 0: a recording
    // whose first frames were deleted was replayed from frame_000005.pgm as frame 0, its truth
    // compared against the wrong frames (found probing: 2 false poses 11.6 px off).
    if (i == 0 && n != 0) {
      throw std::runtime_error(dir + ": frame 0 is missing (the first is " + fs::path(names[0]).filename().string() +
                               "): frames are counted from frame_000000.pgm (the poses' frame column, frames.csv and a "
                               "truth's rows count from there); renumber them from 0");
    }
    if (i > 0 && n != prev + 1) {
      throw std::runtime_error(dir + ": frame " + std::to_string(prev + 1) + " is missing (" + fs::path(names[i - 1]).filename().string() +
                               " is followed by " + fs::path(names[i]).filename().string() +
                               "): every later frame would be taken for the one before it");
    }
    prev = n;
  }
  return names;
}

ReplaySource::ReplaySource(const ScanLimits& limits, const config::ReplayConfig& cfg)
    : TimedScanSource(cfg.clock != "real"), limits_(limits), loop_(cfg.loop) {
  const std::vector<std::string> names = list_pgm_frames(cfg.frames_dir);
  // Memory check before loading: all frames stay resident.
  Image first = read_pgm(names.front());
  const double bytes = static_cast<double>(names.size()) * first.width * first.height * sizeof(std::uint16_t);
  const double phys = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * static_cast<double>(sysconf(_SC_PAGESIZE));
  if (phys > 0 && bytes > 0.5 * phys) {
    throw std::runtime_error(cfg.frames_dir + ": " + std::to_string(names.size()) + " frames need " +
                             std::to_string(static_cast<long long>(bytes / 1048576)) + " MiB, more than half of the " +
                             std::to_string(static_cast<long long>(phys / 1048576)) + " MiB of memory; replay fewer frames");
  }
  // Under an address-space limit (ulimit -v) the frames, and the tracker's bank and buffers
  // after them, must fit what is left of it: found probing, 7000 frames of 1024x768 under 6 GB
  // loaded for 18 s and ended in a bare std::bad_alloc. Half of it, as for physical memory.
  if (const rt::MemoryRoom room = rt::memory_room(); room.address_limited && bytes > 0.5 * static_cast<double>(room.address_left)) {
    throw std::runtime_error(cfg.frames_dir + ": " + std::to_string(names.size()) + " frames need " +
                             std::to_string(static_cast<long long>(bytes / 1048576)) + " MiB, more than half of the " +
                             std::to_string(static_cast<long long>(room.address_left / 1048576)) +
                             " MiB this process may still map under its address-space limit (ulimit -v " +
                             std::to_string(room.address_limit / 1024) + " KiB); replay fewer frames or raise the limit");
  }
  frames_.reserve(names.size());
  frames_.push_back(std::move(first));
  for (std::size_t i = 1; i < names.size(); ++i) {
    frames_.push_back(read_pgm(names[i]));
    if (frames_.back().width != frames_[0].width || frames_.back().height != frames_[0].height) {
      throw std::runtime_error(names[i] + ": size " + std::to_string(frames_.back().width) + "x" +
                               std::to_string(frames_.back().height) + " differs from the first frame's");
    }
    // One detector, one digitiser: a frame of another depth is from another recording.
    if (frames_.back().bits != frames_[0].bits) {
      throw std::runtime_error(names[i] + ": " + std::to_string(frames_.back().bits) + "-bit samples where the first frame has " +
                               std::to_string(frames_[0].bits) + "-bit ones");
    }
  }
  // A frame stored twice (a frozen frame buffer during the recording): an SEM frame carries shot
  // noise in every pixel, so two real scans never match. Replayed as new, the old scene would show
  // the target where it was while it moved on; the repeat is replayed as a bad frame instead.
  repeats_.assign(frames_.size(), 0);
  std::size_t n_repeats = 0;
  for (std::size_t i = 1; i < frames_.size(); ++i) {
    if (frames_[i].pixels != frames_[i - 1].pixels) continue;
    repeats_[i] = 1;
    if (n_repeats++ == 0) first_repeat_ = names[i];
  }
  if (n_repeats > 0) {
    std::fprintf(stderr, "replay: warning: %zu frame(s) repeat the frame before pixel for pixel (first %s): replayed as bad frames\n",
                 n_repeats, first_repeat_.c_str());
  }
  limits_.field_w = frames_[0].width;
  limits_.field_h = frames_[0].height;
  limits_.max_roi_w = std::min(limits_.max_roi_w, limits_.field_w);
  limits_.max_roi_h = std::min(limits_.max_roi_h, limits_.field_h);
  limits_.bits = frames_[0].bits;

  const fs::path csv = fs::path(cfg.frames_dir) / "frames.csv";
  std::error_code ec;
  // A link to nowhere was taken for "no frames.csv" (synthetic time stamps, found probing), where
  // a frame's dangling link is refused: the recording's files are there or named.
  for (const fs::path& f : {csv, fs::path(cfg.frames_dir) / "ground_truth.csv"}) {
    if (fs::is_symlink(fs::symlink_status(f, ec)) && !fs::exists(f, ec))
      throw std::runtime_error(f.string() + ": a dangling link, not a file of the recording");
  }
  if (fs::exists(csv, ec)) t_ns_ = read_frames_csv(csv.string(), frames_.size());
  // A loop moves every later pass on by the recording's span: stamps anywhere in [0, 2^62) are
  // fine once, but a span of ~2^62 ns overflowed the 64-bit clock on the second pass (found
  // probing: t_ns -9.2e18 on 537 poses, exit 0). Looping asks for a span a clock can go on from:
  // at most 2^52 ns (52 days), which leaves room for a thousand passes after the largest stamp.
  if (loop_ && t_ns_.size() > 1 && t_ns_.back() - t_ns_.front() > kMaxLoopSpanNs) {
    throw std::runtime_error(csv.string() + ": its time stamps span " + std::to_string(t_ns_.back() - t_ns_.front()) +
                             " ns (t_ns " + std::to_string(t_ns_.front()) + " .. " + std::to_string(t_ns_.back()) +
                             "); replay.loop moves each pass on by that span and allows at most 2^52 ns (52 days): "
                             "loop a shorter recording, or replay it once (replay.loop: false)");
  }
  const fs::path gt = fs::path(cfg.frames_dir) / "ground_truth.csv";
  if (fs::exists(gt, ec)) {
    truth_.assign(frames_.size(), {});
    for (const TruthRow& row : read_truth_csv(gt.string(), kMaxTargets)) {
      if (row.frame >= static_cast<long long>(frames_.size())) continue;  // a frame this recording does not hold
      truth_[static_cast<std::size_t>(row.frame)][static_cast<std::size_t>(row.target)] = {row.x_px, row.y_px, row.phi_deg, true};
      truth_count_ = static_cast<std::uint8_t>(std::max<int>(truth_count_, row.target + 1));
    }
  }
}

StartResult ReplaySource::start(const ScanRequest& req, FrameSlot& slot) noexcept {
  if (timer_.busy()) return StartResult::kBusy;
  if (index_ >= frames_.size()) {
    if (!loop_) return StartResult::kEnded;
    if (!t_ns_.empty()) {
      const std::int64_t period = frames_.size() > 1 ? (t_ns_.back() - t_ns_.front()) / static_cast<std::int64_t>(frames_.size() - 1) : 0;
      // Bounded (span ≤ 2^52 ns, checked at setup): saturating only past ~1000 passes of the longest.
      const std::int64_t step = t_ns_.back() - t_ns_.front() + period;
      // Room for a pass more and a scan after its last stamp (the scan's end is t0 + its time).
      const std::int64_t room = std::numeric_limits<std::int64_t>::max() - t_ns_.back() -
                                loop_offset_ns_ - kMaxLoopSpanNs;
      if (step > room) return StartResult::kEnded;  // no later pass can be stamped: the source ends
      loop_offset_ns_ += step;
    }
    index_ = 0;
  }
  std::uint32_t dwell = 0;
  const StartResult check = check_scan_request(limits_, req, slot.capacity_pixels, dwell);
  if (check != StartResult::kStarted) return check;
  const Image& f = frames_[index_];
  const Roi& r = req.roi;
  for (int y = 0; y < r.h; ++y) {
    const std::uint16_t* src = &f.pixels[static_cast<std::size_t>(r.y + y) * f.width + r.x];
    std::memcpy(slot.pixels + static_cast<std::size_t>(y) * r.w, src, static_cast<std::size_t>(r.w) * sizeof(Pixel));
  }
  std::int64_t t0 = now_ns();
  if (timer_.is_virtual() && !t_ns_.empty()) t0 = std::max(t0, t_ns_[index_] + loop_offset_ns_);
  timer_.begin(slot, req, limits_, dwell, seq_++, t0);
  FrameMeta& m = slot.meta;
  if (repeats_[index_]) m.status = FrameStatus::kBad;
  m.truth_count = truth_count_;
  for (int t = 0; t < kMaxTargets; ++t) m.truth[t] = truth_.empty() ? TargetTruth{} : truth_[index_][static_cast<std::size_t>(t)];
  ++index_;
  return StartResult::kStarted;
}

}  // namespace sempose::hal
