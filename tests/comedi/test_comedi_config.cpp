// The comedi: section: defaults, a full NI-style setting, and every refusal naming the key,
// the value and what is allowed. (What only the card can say is in test_comedi_hw.cpp.)
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "sempose/config/app_config.hpp"
#include "sempose/config/comedi_config.hpp"
#include "sempose/config/reader.hpp"

namespace cfg = sempose::config;

namespace {

std::string read(const char* yaml, cfg::ComediConfig& out) {
  cfg::Errors errors("test.yaml");
  {
    cfg::Section s(YAML::Load(yaml), "comedi", errors);
    cfg::read_comedi(s, out);
  }
  return errors.joined();
}

TEST(ComediSection, DefaultsAreAComediTestSetup) {
  cfg::ComediConfig c;
  EXPECT_EQ(read("{}", c), "");
  EXPECT_EQ(c.device, "/dev/comedi0");
  EXPECT_EQ(c.device_path(), "/dev/comedi0");
  EXPECT_EQ(c.detector_channels, (std::vector<std::int32_t>{0}));
  EXPECT_EQ(c.trigger, "internal");
  EXPECT_EQ(c.oversample, 1);
}

TEST(ComediSection, ReadsAnNiStyleSetup) {
  cfg::ComediConfig c;
  EXPECT_EQ(read("{device: /dev/comedi2, ai_subdevice: 0, ao_subdevice: 1, detector_channels: [0, 1], ai_range: 1, "
                 "x_channel: 1, y_channel: 0, x_volts: [-4.5, 4.5], y_volts: [3.2, -3.2], park_volts: [-9, -9], "
                 "detector_volts: [0.2, 2.5], settle_samples: 10, flyback_samples: 40, oversample: 2, "
                 "trigger: ai_start, ao_start_arg: 18, timeout_ms: 500}",
                 c),
            "");
  EXPECT_EQ(c.device, "/dev/comedi2");
  EXPECT_EQ(c.detector_channels.size(), 2u);
  EXPECT_EQ(c.x_channel, 1);
  EXPECT_EQ(c.x_volts, (std::vector<double>{-4.5, 4.5}));
  EXPECT_EQ(c.detector_volts, (std::vector<double>{0.2, 2.5}));
  EXPECT_EQ(c.trigger, "ai_start");
  EXPECT_EQ(c.ao_start_arg, 18u);
}

TEST(ComediSection, RefusalsNameKeyValueAndRange) {
  struct Case {
    const char* yaml;
    const char* expect;
  } cases[] = {
      {"{detector_channels: []}", "comedi.detector_channels: 0 channel(s) given; allowed: 1 or 2"},
      {"{detector_channels: [0, 1, 2]}", "comedi.detector_channels: 3 channel(s) given"},
      {"{detector_channels: [3, 3]}", "comedi.detector_channels: the same channel twice"},
      {"{x_channel: 1, y_channel: 1}", "comedi.y_channel: 1 is the same AO channel as comedi.x_channel"},
      {"{x_volts: [1, 1]}", "comedi.x_volts: left and right are equal"},
      {"{y_volts: [2]}", "comedi.y_volts: 1 value(s) given; expected two"},
      {"{park_volts: [0, 200]}", "comedi.park_volts[1]: 200 is outside the allowed range"},
      {"{oversample: 0}", "comedi.oversample: 0 is outside the allowed range"},
      {"{trigger: external}", "comedi.trigger"},
      {"{device: ''}", "comedi.device: is empty"},
      {"{device: dev/comedi0}", "comedi.device: 'dev/comedi0' is a relative path: give the device node's absolute path"},
      {"{settle: 3}", "comedi.settle"},  // unknown key (a typo)
  };
  for (const Case& k : cases) {
    cfg::ComediConfig c;
    const std::string e = read(k.yaml, c);
    EXPECT_NE(e.find(k.expect), std::string::npos) << k.yaml << " -> " << e;
    EXPECT_NE(e.find("test.yaml"), std::string::npos) << e;
  }
}

// Two volts out of range were read as 0 each and then also called "equal" (found probing).
TEST(ComediSection, AVoltsPairOutOfRangeIsNotAlsoCalledEqual) {
  cfg::ComediConfig c;
  const std::string e = read("{x_volts: [1e300, -1e300]}", c);
  EXPECT_NE(e.find("comedi.x_volts[0]: 1e300 is outside the allowed range"), std::string::npos) << e;
  EXPECT_EQ(e.find("equal"), std::string::npos) << e;
}

TEST(ComediSection, SourceComediIsAcceptedByTheAppConfig) {
  const std::string path = ::testing::TempDir() + "comedi_app.yaml";
  std::ofstream(path) << "source: comedi\ncomedi: {device: /dev/comedi1, trigger: ai_start}\n";
  cfg::AppConfig app;
  std::string err;
  EXPECT_TRUE(cfg::load_app_config(path, app, err)) << err;
  EXPECT_EQ(app.source, "comedi");
  EXPECT_EQ(app.comedi.device, "/dev/comedi1");
  EXPECT_EQ(cfg::scan_device_path(app), "/dev/comedi1");
  app.source = "sim";
  EXPECT_EQ(cfg::scan_device_path(app), "");
}

// The example names a pattern the operator records on the microscope (gripper_x2000.pgm beside
// the config); the config check requires it to exist, so the test puts a stand-in beside a copy.
TEST(ComediSection, TheShippedNiExampleIsValid) {
  const std::string dir = ::testing::TempDir();
  {
    std::ifstream in(std::string(SEMPOSE_SOURCE_DIR) + "/config/comedi_ni625x.yaml");
    std::ofstream(dir + "comedi_ni625x.yaml") << in.rdbuf();
    std::ofstream pgm(dir + "gripper_x2000.pgm", std::ios::binary);
    pgm << "P5\n128 128\n255\n" << std::string(128 * 128, '\x80');
  }
  cfg::AppConfig app;
  std::string err;
  EXPECT_TRUE(cfg::load_app_config(dir + "comedi_ni625x.yaml", app, err)) << err;
  EXPECT_EQ(app.source, "comedi");
  EXPECT_EQ(app.comedi.trigger, "ai_start");
  EXPECT_EQ(app.scan.min_dwell_ns, 1000u);
}

}  // namespace
