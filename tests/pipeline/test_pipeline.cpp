// The whole pipeline (real simulator, real trackers, RT threads) in virtual time: zero heap
// allocations on every RT thread over 10,000+ frames, and end-to-end tracking against the
// simulator's ground truth. Also the sleep-polling pipeline in real time on a short run.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "sempose/config/app_config.hpp"
#include "sempose/hal/source_factory.hpp"
#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pipeline/tracker_setup.hpp"
#include "sempose/pose/tracker.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {
namespace {

// Keeps every pose in a buffer made at setup (publish is RT: no allocation).
class RecordingSink final : public PoseSink {
 public:
  explicit RecordingSink(std::size_t capacity) : poses_(capacity) {}
  PublishResult publish(const PoseRecord& pose, std::int64_t) noexcept override {
    if (count_ >= poses_.size()) return PublishResult::kDropped;
    poses_[count_++] = pose;
    return PublishResult::kSent;
  }
  void service(const PipelineStatus& s, std::int64_t) noexcept override {
    ++services_;
    last_ack_.store(s.last_command_seq, std::memory_order_relaxed);
    rejected_.store(s.commands_rejected, std::memory_order_relaxed);
  }
  int last_ack() const { return last_ack_.load(std::memory_order_relaxed); }
  std::uint32_t rejected() const { return rejected_.load(std::memory_order_relaxed); }
  bool next_command(Command& out) noexcept override {
    if (pending_.load(std::memory_order_acquire) == 0) return false;
    out = command_;
    pending_.store(0, std::memory_order_release);
    return true;
  }
  void inject(const Command& c) {
    command_ = c;
    pending_.store(1, std::memory_order_release);
  }
  std::size_t count() const { return count_; }
  const PoseRecord& operator[](std::size_t i) const { return poses_[i]; }
  std::uint64_t services() const { return services_; }

 private:
  std::vector<PoseRecord> poses_;
  std::size_t count_ = 0;
  std::uint64_t services_ = 0;
  Command command_{};
  std::atomic<int> pending_{0};
  std::atomic<int> last_ack_{0};
  std::atomic<std::uint32_t> rejected_{0};
};

struct Rig {
  config::AppConfig cfg;
  std::unique_ptr<hal::ScanSource> source;
  TrackerSetup trackers;
  std::unique_ptr<RecordingSink> sink;
  std::unique_ptr<StageClock> clock;
  std::unique_ptr<Pipeline> pipeline;

  explicit Rig(const std::string& yaml, std::size_t max_poses) {
    std::string errors;
    const bool ok = config::load_app_config(yaml, cfg, errors);
    EXPECT_TRUE(ok) << errors;
    rt::Status st;
    source = hal::make_scan_source(cfg.source, cfg.scan, cfg.sim, cfg.replay, st);
    EXPECT_TRUE(source) << st.message;
    st = make_trackers(cfg, source->limits(), trackers);
    EXPECT_TRUE(st.ok) << st.message;
    sink = std::make_unique<RecordingSink>(max_poses);
    std::vector<pose::Tracker*> raw;
    for (auto& t : trackers.trackers) raw.push_back(t.get());
    clock = make_stage_clock(cfg);
    pipeline = std::make_unique<Pipeline>(cfg.pipeline, cfg.governor, *source, raw, *sink, *clock);
  }
};

const std::string kVirtualYaml = std::string(SEMPOSE_SOURCE_DIR) + "/tests/pipeline/pipeline_virtual.yaml";

TEST(Pipeline, TenThousandFramesInVirtualTimeWithoutHeapCallsOnRtThreads) {
  constexpr std::uint64_t kFrames = 10'000;
  Rig rig(kVirtualYaml, kFrames + 16);
  ASSERT_TRUE(rig.pipeline);
  ASSERT_TRUE(uses_virtual_clock(rig.cfg));
  rig.pipeline->stop_after_frames(kFrames);
  const std::uint64_t allocs_before = rt::alloc::allocations();
  const std::int64_t t0 = rt::now_ns();
  ASSERT_TRUE(rig.pipeline->start(false).ok);
  rig.pipeline->join();
  const auto& c = rig.pipeline->counters();
  std::printf("%llu frames in %.1f s wall (virtual time)\n", static_cast<unsigned long long>(c.frames_scanned.get()),
              (rt::now_ns() - t0) * 1e-9);

  // Every RT thread made no heap call in its loop (RtThread armed the counter).
  EXPECT_EQ(c.acquisition_allocs.get(), 0u);
  EXPECT_EQ(c.correlation_allocs.get(), 0u);
  EXPECT_EQ(c.output_allocs.get(), 0u);
  if (rt::alloc::counts_malloc()) {
    EXPECT_EQ(rt::alloc::allocations(), allocs_before);
  }

  EXPECT_EQ(c.frames_scanned.get(), kFrames);
  EXPECT_EQ(rig.pipeline->dropped_frames(), 0u) << "virtual time paces acquisition: nothing is dropped";
  EXPECT_EQ(c.sent.get(), kFrames);
  ASSERT_EQ(rig.sink->count(), kFrames);
  EXPECT_GT(rig.sink->services(), 0u);

  // End to end: the real tracker follows the simulated needle.
  std::size_t tracked = 0, uncertain = 0;
  std::vector<double> errors_px;
  for (std::size_t i = 0; i < rig.sink->count(); ++i) {
    const PoseRecord& p = (*rig.sink)[i];
    EXPECT_EQ(p.pose_seq, static_cast<std::uint32_t>(i));
    uncertain += p.state == pose::TrackState::kUncertain && p.truth_present;
    if (p.state != pose::TrackState::kTracking || !p.truth_present) continue;
    ++tracked;
    errors_px.push_back(std::hypot(p.x_px - p.truth_x_px, p.y_px - p.truth_y_px));
  }
  ASSERT_FALSE(errors_px.empty());
  std::sort(errors_px.begin(), errors_px.end());
  const double median_px = errors_px[errors_px.size() / 2];
  const double p90_px = errors_px[errors_px.size() * 9 / 10];
  const double p999_px = errors_px[errors_px.size() * 999 / 1000];
  const std::uint64_t searches = c.targets[0].searches.get();
  std::printf("tracked %.2f %%, start searches %llu, position error vs truth: median %.2f px, p90 %.2f px, "
              "p99.9 %.2f px, max %.2f px\n",
              100.0 * static_cast<double>(tracked) / kFrames, static_cast<unsigned long long>(searches), median_px,
              p90_px, p999_px, errors_px.back());
  // Followed (TRACKING, or UNCERTAIN: the target held but a pose whose σ or the stream's
  // noise allows > 3 px / 10° more often than tracker.max_false_probability) on 99.9 % of the
  // frames as before the UNCERTAIN state; reported TRACKING on 99 % (measured 99.57 %).
  std::printf("UNCERTAIN %zu of %zu frames\n", uncertain, static_cast<std::size_t>(kFrames));
  EXPECT_GE(tracked + uncertain, kFrames * 999 / 1000) << "followed share";
  EXPECT_GE(tracked, kFrames * 99 / 100) << "tracked share";
  EXPECT_LE(searches, 2u) << "the target is found once and held: no repeated start searches";
  EXPECT_LT(median_px, 0.5) << "position error against the simulator's truth";
  EXPECT_LT(p90_px, 1.0) << "position error against the simulator's truth";
  EXPECT_LT(p999_px, 2.0) << "no TRACKING pose on a false match";

  // Histograms: one sample per frame, timestamps ordered.
  const auto h = rig.pipeline->histograms().snapshot();
  for (const auto& s : h) EXPECT_EQ(s.count, kFrames) << s.name;
}

TEST(Pipeline, CommandsReachTheTrackersWithoutLocks) {
  Rig rig(kVirtualYaml, 4096);
  rig.pipeline->stop_after_frames(600);
  ASSERT_TRUE(rig.pipeline->start(false).ok);
  // Re-acquire all targets mid-run: the tracker must report it and search again.
  while (rig.pipeline->counters().sent.get() < 200) rt::sleep_until_ns(rt::now_ns() + 100'000);
  Command c;
  c.kind = CommandKind::kReacquire;
  c.target = 0xFF;
  rig.sink->inject(c);
  rig.pipeline->join();
  EXPECT_EQ(rig.pipeline->counters().commands.get(), 1u);
  EXPECT_GE(rig.pipeline->counters().targets[0].searches.get(), 2u) << "start search + commanded re-acquisition";
}

// A command naming a pattern set or target that does not exist, or a scale the tracker cannot
// follow, does nothing, is counted as rejected and is never acknowledged; a valid one is
// acknowledged with its seq once applied.
TEST(Pipeline, CommandsNamingNothingAreRejectedNotAcknowledged) {
  Rig rig(kVirtualYaml, 4096);
  rig.pipeline->stop_after_frames(900);
  ASSERT_TRUE(rig.pipeline->start(false).ok);
  auto send = [&](Command c) {
    while (rig.pipeline->counters().sent.get() < 100) rt::sleep_until_ns(rt::now_ns() + 100'000);
    const std::uint64_t before = rig.pipeline->counters().commands.get() + rig.pipeline->counters().commands_rejected.get();
    rig.sink->inject(c);
    while (rig.pipeline->counters().commands.get() + rig.pipeline->counters().commands_rejected.get() == before &&
           !rig.pipeline->finished())
      rt::sleep_until_ns(rt::now_ns() + 100'000);
    const std::uint64_t sent = rig.pipeline->counters().sent.get();
    while (rig.pipeline->counters().sent.get() < sent + 3 && !rig.pipeline->finished())
      rt::sleep_until_ns(rt::now_ns() + 100'000);  // a few output cycles: the heartbeat status is current
  };
  Command select_missing;
  select_missing.kind = CommandKind::kSelectPatternSet;
  select_missing.arg = 5;  // one pattern set configured
  select_missing.seq = 21;
  send(select_missing);
  Command reacquire_missing;
  reacquire_missing.kind = CommandKind::kReacquire;
  reacquire_missing.target = 3;  // one target configured
  reacquire_missing.seq = 22;
  send(reacquire_missing);
  // An existing set told an nm/px at which the target would be 1000x its pattern's size (a
  // typo in the controller: pm instead of nm) used to be clamped to the tracked range and taken.
  Command select_beyond_scale;
  select_beyond_scale.kind = CommandKind::kSelectPatternSet;
  select_beyond_scale.arg = 0;
  select_beyond_scale.nm_per_px = 0.04;  // the simulator's pattern is recorded at 40 nm/px
  select_beyond_scale.seq = 24;
  send(select_beyond_scale);
  EXPECT_EQ(rig.pipeline->counters().commands_rejected.get(), 3u);
  EXPECT_EQ(rig.pipeline->counters().commands.get(), 0u);
  EXPECT_EQ(rig.sink->last_ack(), 0) << "a refused command must not be acknowledged";
  EXPECT_EQ(rig.sink->rejected(), 3u);
  EXPECT_EQ(rig.pipeline->counters().targets[0].searches.get(), 1u) << "nothing was re-acquired";
  Command reacquire;
  reacquire.kind = CommandKind::kReacquire;
  reacquire.target = 0;
  reacquire.seq = 23;
  send(reacquire);
  rig.pipeline->join();
  EXPECT_EQ(rig.pipeline->counters().commands.get(), 1u);
  EXPECT_EQ(rig.sink->last_ack(), 23);
}

}  // namespace
}  // namespace sempose::pipeline
