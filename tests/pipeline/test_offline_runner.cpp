// The offline runner against the RT pipeline on the simulated SEM (virtual clock, real
// trackers, the pipeline's threads): the same configuration gives the same poses, bit for
// bit, with the same frame numbers, time stamps and dwells — the runner is the pipeline's
// path without threads, not a second tracker loop. Also: it stops at a finite source's end.
#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "sempose/config/app_config.hpp"
#include "sempose/hal/source_factory.hpp"
#include "sempose/pipeline/offline_runner.hpp"
#include "sempose/pipeline/pipeline.hpp"
#include "sempose/pipeline/stage_clock.hpp"
#include "sempose/pipeline/tracker_setup.hpp"
#include "sempose/pose/tracker.hpp"

namespace sempose::pipeline {
namespace {

class KeepAll final : public PoseSink {
 public:
  explicit KeepAll(std::size_t capacity) { poses.reserve(capacity); }
  PublishResult publish(const PoseRecord& p, std::int64_t) noexcept override {
    if (poses.size() == poses.capacity()) return PublishResult::kDropped;  // never grows on an RT thread
    poses.push_back(p);
    return PublishResult::kSent;
  }
  std::vector<PoseRecord> poses;
};

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

struct Inputs {
  std::unique_ptr<hal::ScanSource> source;
  TrackerSetup trackers;
  std::vector<pose::Tracker*> raw;
  explicit Inputs(const config::AppConfig& cfg) {
    rt::Status st;
    source = hal::make_scan_source(cfg.source, cfg.scan, cfg.sim, cfg.replay, st);
    EXPECT_TRUE(source) << st.message;
    st = make_trackers(cfg, source->limits(), trackers);
    EXPECT_TRUE(st.ok) << st.message;
    for (auto& t : trackers.trackers) raw.push_back(t.get());
  }
};

config::AppConfig two_target_sim() {
  // The pipeline test's virtual-time scene plus a second target, so the schedule and the
  // governor's shared compute estimate are exercised too.
  config::AppConfig cfg;
  std::string errors;
  const std::string yaml = std::string(SEMPOSE_SOURCE_DIR) + "/tests/pipeline/pipeline_virtual.yaml";
  EXPECT_TRUE(config::load_app_config(yaml, cfg, errors)) << errors;
  EXPECT_FALSE(cfg.sim.targets.empty());
  cfg.sim.targets.push_back(cfg.sim.targets.front());
  cfg.sim.targets.back().x_px -= 300;
  cfg.sim.targets.back().y_px += 200;
  cfg.pipeline.schedule = {0, 1, 1};  // not plain round robin
  return cfg;
}

TEST(OfflineRunner, GivesThePipelinesPosesBitForBitOnTheSimulator) {
  constexpr std::uint64_t kFrames = 240;
  const config::AppConfig cfg = two_target_sim();
  ASSERT_TRUE(uses_virtual_clock(cfg));
  const std::unique_ptr<StageClock> clock = make_stage_clock(cfg);

  Inputs piped(cfg);
  KeepAll from_pipeline(kFrames + 16);
  {
    Pipeline pipe(cfg.pipeline, cfg.governor, *piped.source, piped.raw, from_pipeline, *clock);
    pipe.stop_after_frames(kFrames);
    ASSERT_TRUE(pipe.start(false).ok);
    pipe.join();
  }
  Inputs offline(cfg);
  KeepAll from_runner(kFrames + 16);
  OfflineRunner runner(cfg.pipeline, cfg.governor, *offline.source, offline.raw, from_runner, *clock);
  OfflineRunStats stats;
  ASSERT_TRUE(runner.run(kFrames, stats).ok);

  ASSERT_EQ(from_pipeline.poses.size(), kFrames);
  ASSERT_EQ(from_runner.poses.size(), kFrames);
  EXPECT_EQ(stats.frames, kFrames);
  int tracking = 0, per_target[2] = {0, 0};
  for (std::size_t i = 0; i < kFrames; ++i) {
    const PoseRecord& a = from_pipeline.poses[i];
    const PoseRecord& b = from_runner.poses[i];
    SCOPED_TRACE("pose " + std::to_string(i));
    EXPECT_EQ(a.frame_seq, b.frame_seq);
    EXPECT_EQ(a.target, b.target);
    EXPECT_EQ(a.pose_seq, b.pose_seq);
    EXPECT_EQ(a.state, b.state);
    EXPECT_TRUE(same_bits(a.x_px, b.x_px) && same_bits(a.y_px, b.y_px) && same_bits(a.phi_deg, b.phi_deg))
        << a.x_px << "," << a.y_px << "," << a.phi_deg << " vs " << b.x_px << "," << b.y_px << "," << b.phi_deg;
    EXPECT_EQ(a.score, b.score);
    EXPECT_EQ(a.dwell_ns, b.dwell_ns);
    EXPECT_EQ(a.t_scan_end_ns, b.t_scan_end_ns);
    EXPECT_EQ(a.t_pose_done_ns, b.t_pose_done_ns);
    tracking += a.state == pose::TrackState::kTracking;
    ++per_target[a.target & 1];
  }
  // The schedule 0, 1, 1: a third of the scans for target 0.
  EXPECT_EQ(per_target[0], static_cast<int>(kFrames / 3));
  EXPECT_GT(tracking, static_cast<int>(kFrames * 9 / 10)) << "compare real tracking, not two lost tracks";
}

TEST(OfflineRunner, RefusesAScheduleNamingNoTarget) {
  config::AppConfig cfg = two_target_sim();
  cfg.pipeline.schedule = {0, 5};
  Inputs in(cfg);
  KeepAll sink(4);
  const VirtualStageClock clock(0);
  OfflineRunner runner(cfg.pipeline, cfg.governor, *in.source, in.raw, sink, clock);
  OfflineRunStats stats;
  const rt::Status st = runner.run(10, stats);
  EXPECT_FALSE(st.ok);
  EXPECT_NE(st.message.find("pipeline.schedule"), std::string::npos) << st.message;
  EXPECT_EQ(stats.frames, 0u);
}

}  // namespace
}  // namespace sempose::pipeline
