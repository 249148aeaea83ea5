// Replay serves each requested ROI as a crop of the current recorded frame, one frame per scan.
#include <gtest/gtest.h>

#include <fstream>

#include "sempose/hal/pgm.hpp"
#include "sempose/hal/replay_source.hpp"
#include "sempose/hal/source_factory.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "test_util.hpp"

namespace sempose::hal {
namespace {

// Frames whose every pixel encodes (frame, x, y), so a crop can be checked exactly.
std::vector<Image> write_sequence(const std::filesystem::path& dir, int n, bool csv, bool truth) {
  std::vector<Image> frames;
  for (int f = 0; f < n; ++f) {
    Image img;
    img.width = 80;
    img.height = 60;
    img.bits = 16;
    for (int y = 0; y < 60; ++y)
      for (int x = 0; x < 80; ++x) img.pixels.push_back(static_cast<std::uint16_t>(f * 10000 + y * 100 + x));
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.pgm", f);
    write_pgm((dir / name).string(), img);
    frames.push_back(img);
  }
  if (csv) {
    std::ofstream o(dir / "frames.csv");
    o << "frame,t_ns\n";
    for (int f = 0; f < n; ++f) o << f << "," << 5'000'000'000LL + f * 40'000'000LL << "\n";
  }
  if (truth) {
    std::ofstream o(dir / "ground_truth.csv");
    o << "frame,x_px,y_px,phi_deg\n";
    for (int f = 0; f < n; ++f) o << f << "," << 10 + f << ",20.5,-3.25\n";
  }
  return frames;
}

ScanLimits limits() {
  ScanLimits lim;
  lim.max_roi_w = lim.max_roi_h = 32;
  return lim;
}

TEST(Replay, ServesCropsOfConsecutiveFramesThenEnds) {
  const auto dir = test::temp_dir("replay");
  const auto frames = write_sequence(dir, 3, false, false);
  config::ReplayConfig rc;
  rc.frames_dir = dir.string();
  ReplaySource src(limits(), rc);
  EXPECT_EQ(src.limits().field_w, 80) << "field from the frames";
  EXPECT_EQ(src.limits().bits, 16);
  FramePool pool(1, 80 * 60);
  std::int64_t last_end = 0;
  for (int f = 0; f < 3; ++f) {
    const Roi roi{5 + f, 7, 32, 20};
    ASSERT_EQ(src.start({roi, 500, 0}, pool[0]), StartResult::kStarted);
    ASSERT_EQ(src.poll(), PollResult::kDone);
    const FrameMeta& m = pool[0].meta;
    EXPECT_EQ(m.seq, static_cast<std::uint64_t>(f));
    EXPECT_EQ(m.roi, roi);
    EXPECT_EQ(m.t_scan_end_ns - m.t_scan_start_ns, limits().scan_time_ns(32, 20, 500));
    EXPECT_GE(m.t_scan_start_ns, last_end);
    last_end = m.t_scan_end_ns;
    for (int y = 0; y < roi.h; ++y)
      for (int x = 0; x < roi.w; ++x)
        ASSERT_EQ(pool[0].pixels[y * roi.w + x], frames[f].at(roi.x + x, roi.y + y)) << f << " " << x << "," << y;
  }
  EXPECT_EQ(src.start({{0, 0, 16, 16}, 500, 0}, pool[0]), StartResult::kEnded);
  EXPECT_EQ(src.start({{0, 0, 80, 60}, 500, 0}, pool[0]), StartResult::kEnded);
}

TEST(Replay, LoopsUsesFramesCsvTimesAndGroundTruthWithoutAllocating) {
  const auto dir = test::temp_dir("replay_loop");
  write_sequence(dir, 2, true, true);
  config::ReplayConfig rc;
  rc.frames_dir = dir.string();
  rc.loop = true;
  rt::Status st;
  auto src = make_scan_source("replay", limits(), {}, rc, st);
  ASSERT_NE(src, nullptr) << st.message;
  FramePool pool(1, 80 * 60);
  std::vector<std::int64_t> starts;
  starts.reserve(8);
  std::uint64_t allocs = 0;
  {
    rt::alloc::ScopedArm arm;
    for (int i = 0; i < 6; ++i) {
      if (src->start({{0, 0, 80, 60}, 250, 0}, pool[0]) != StartResult::kStarted) break;
      src->poll();
      starts.push_back(pool[0].meta.t_scan_start_ns);
    }
    allocs = rt::alloc::this_thread_allocations();
  }
  EXPECT_EQ(allocs, 0u);
  ASSERT_EQ(starts.size(), 6u);
  EXPECT_EQ(starts[0], 5'000'000'000LL);
  EXPECT_EQ(starts[1], 5'040'000'000LL);
  EXPECT_EQ(starts[2], 5'080'000'000LL) << "a loop continues the time line";
  EXPECT_EQ(pool[0].pixels[0], 10000) << "6th scan = frame 1";
  EXPECT_EQ(pool[0].meta.truth_count, 1);
  EXPECT_TRUE(pool[0].meta.truth[0].present);
  EXPECT_DOUBLE_EQ(pool[0].meta.truth[0].x_px, 11);
  EXPECT_DOUBLE_EQ(pool[0].meta.truth[0].phi_deg, -3.25);
}

TEST(Replay, SetupErrorsNameTheProblem) {
  config::ReplayConfig rc;
  rc.frames_dir = "/nonexistent/frames";
  rt::Status st;
  EXPECT_EQ(make_scan_source("replay", limits(), {}, rc, st), nullptr);
  EXPECT_NE(st.message.find("/nonexistent/frames"), std::string::npos) << st.message;
  const auto empty = test::temp_dir("replay_empty");
  rc.frames_dir = empty.string();
  EXPECT_EQ(make_scan_source("replay", limits(), {}, rc, st), nullptr);
  EXPECT_NE(st.message.find("no *.pgm"), std::string::npos) << st.message;
  const auto mixed = test::temp_dir("replay_mixed");
  write_sequence(mixed, 1, false, false);
  Image small;
  small.width = small.height = 10;
  small.pixels.assign(100, 0);
  write_pgm((mixed / "frame_000001.pgm").string(), small);
  rc.frames_dir = mixed.string();
  EXPECT_EQ(make_scan_source("replay", limits(), {}, rc, st), nullptr);
  EXPECT_NE(st.message.find("differs"), std::string::npos) << st.message;
  // Same size, other depth: an 8-bit frame after 16-bit ones.
  const auto depth = test::temp_dir("replay_depth");
  write_sequence(depth, 1, false, false);
  Image eight;
  eight.width = 80;
  eight.height = 60;
  eight.bits = 8;
  eight.pixels.assign(80 * 60, 7);
  write_pgm((depth / "frame_000001.pgm").string(), eight);
  rc.frames_dir = depth.string();
  EXPECT_EQ(make_scan_source("replay", limits(), {}, rc, st), nullptr);
  EXPECT_NE(st.message.find("frame_000001.pgm: 8-bit samples where the first frame has 16-bit ones"), std::string::npos)
      << st.message;
}

}  // namespace
}  // namespace sempose::hal
