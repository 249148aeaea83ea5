// The scan:, sim: and replay: YAML sections: values land in the structs, bad ones are named.
#include <gtest/gtest.h>

#include <fstream>

#include "sempose/config/reader.hpp"
#include "sempose/config/scan_config.hpp"
#include "sempose/config/sim_config.hpp"
#include "test_util.hpp"

namespace sempose::config {
namespace {

std::string read(const std::string& yaml, ScanLimits& scan, SimConfig& sim, ReplayConfig& replay) {
  const auto path = (hal::test::temp_dir("cfg") / "c.yaml").string();
  std::ofstream(path) << yaml;
  Errors errors(path);
  YAML::Node root = load_file(path, errors);
  {
    Section top(root, "", errors);
    Section a = top.child("scan");
    read_scan(a, scan);
    Section b = top.child("sim");
    read_sim(b, sim);
    Section c = top.child("replay");
    read_replay(c, replay);
  }
  return errors.joined();
}

TEST(ScanConfig, ReadsAllSections) {
  ScanLimits scan;
  SimConfig sim;
  ReplayConfig replay;
  const std::string err = read(R"(
scan: {field_w: 640, field_h: 480, max_roi_w: 192, max_roi_h: 160, min_dwell_ns: 200, max_dwell_ns: 5000,
       dwell_step_ns: 100, line_flyback_ns: 1500, bits: 16}
sim:
  seed: 9
  clock: virtual
  beam_current_pa: 80
  drift: [{amplitude_px: 1.5, period_s: 12, direction_deg: 45}]
  background: {source: procedural, mean: 0.2}
  targets:
    - texture: {path: needle.pgm, crop: [1, 2, 30, 40], mask: threshold, mask_level: 0.4}
      start: [100, 120, 15]
      trajectory: {kind: steps, amplitude_x_px: 5, period_s: 0.5, steps: 3}
    - texture: {source: gripper}
      size: [90, 70]
replay: {frames_dir: rec, loop: true}
)",
                               scan, sim, replay);
  EXPECT_EQ(err, "");
  EXPECT_EQ(scan.field_w, 640);
  EXPECT_EQ(scan.bits, 16);
  EXPECT_EQ(scan.line_flyback_ns, 1500u);
  EXPECT_EQ(sim.seed, 9u);
  EXPECT_EQ(sim.clock, "virtual");
  ASSERT_EQ(sim.drift.size(), 1u);
  EXPECT_EQ(sim.drift[0].amplitude_px, 1.5);
  ASSERT_EQ(sim.targets.size(), 2u);
  EXPECT_EQ(sim.targets[0].texture.source, "image");
  EXPECT_EQ(sim.targets[0].texture.crop_h, 40);
  EXPECT_EQ(sim.targets[0].phi_deg, 15);
  EXPECT_EQ(sim.targets[0].trajectory.kind, "steps");
  EXPECT_EQ(sim.targets[1].width_px, 90);
  EXPECT_TRUE(replay.loop);
  EXPECT_EQ(replay.frames_dir, "rec");
}

TEST(ScanConfig, BadValuesAreNamed) {
  ScanLimits scan;
  SimConfig sim;
  ReplayConfig replay;
  const std::string err = read(R"(
scan: {bits: 12, min_dwell_ns: 900, max_dwell_ns: 800, max_roi_w: 2000}
sim:
  clock: sometimes
  yield: -1
  targets:
    - texture: {source: image}
      trajectory: {kind: teleport}
      colour: red
)",
                               scan, sim, replay);
  for (const char* expected : {"scan.bits: 12 is not one of: 8, 16", "scan.min_dwell_ns", "scan.max_roi_w",
                               "sim.clock: 'sometimes'", "sim.yield", "sim.targets[0].texture.path",
                               "sim.targets[0].trajectory.kind: 'teleport'", "sim.targets[0].colour: unknown key"}) {
    EXPECT_NE(err.find(expected), std::string::npos) << expected << "\n" << err;
  }
}

// Each drift term is summed for every scanned line on the RT path: 200,000 were accepted (sim
// took 18 s for two 320x240 frames). Bounded at kMaxDriftTerms, named with the count.
TEST(ScanConfig, DriftTermsAreBounded) {
  ScanLimits scan;
  SimConfig sim;
  ReplayConfig replay;
  auto drift = [](std::size_t n) {
    std::string y = "sim:\n  drift:\n";
    for (std::size_t i = 0; i < n; ++i) y += "    - {amplitude_px: 0.1, period_s: 10}\n";
    return y;
  };
  EXPECT_EQ(read(drift(kMaxDriftTerms), scan, sim, replay), "");
  EXPECT_EQ(sim.drift.size(), kMaxDriftTerms);
  const std::string err = read(drift(kMaxDriftTerms + 1), scan, sim, replay);
  EXPECT_NE(err.find("sim.drift: " + std::to_string(kMaxDriftTerms + 1) + " terms; at most " +
                     std::to_string(kMaxDriftTerms) + " are allowed"),
            std::string::npos)
      << err;
}

TEST(ScanConfig, DefaultsNeedNoSection) {
  const SimConfig sim;
  const ScanLimits scan;
  EXPECT_EQ(scan.field_w, 1024);
  EXPECT_EQ(scan.field_h, 768);
  ASSERT_EQ(sim.targets.size(), 2u);
  EXPECT_TRUE(sim.targets[0].enabled);
  EXPECT_NE(sim.targets[0].texture.path.find("needle_contact_eb.pgm"), std::string::npos);
  EXPECT_FALSE(sim.targets[1].enabled);
  EXPECT_EQ(sim.targets[1].texture.source, "gripper");
}

}  // namespace
}  // namespace sempose::config
