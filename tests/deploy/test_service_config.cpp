// The `service:` section: defaults, ranges, and the stall timeout checked against the longest
// scan the pipeline starts (a full field at governor.initial_dwell_ns), errors naming the key.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "sempose/config/app_config.hpp"

namespace {

struct Loaded {
  bool ok;
  std::string errors;
  sempose::config::AppConfig cfg;
};

Loaded load(const std::string& yaml) {
  const auto path = std::filesystem::temp_directory_path() / ("sempose_service_" + std::to_string(::getpid()) + ".yaml");
  std::ofstream(path) << yaml;
  Loaded l;
  l.ok = sempose::config::load_app_config(path.string(), l.cfg, l.errors);
  std::filesystem::remove(path);
  return l;
}

}  // namespace

TEST(ServiceConfig, DefaultsAndValues) {
  auto l = load("source: sim\n");
  ASSERT_TRUE(l.ok) << l.errors;
  EXPECT_EQ(l.cfg.service.stall_timeout_ms, 2000u);
  EXPECT_EQ(l.cfg.service.stop_timeout_ms, 5000u);
  l = load("service: {stall_timeout_ms: 1000, stop_timeout_ms: 1500}\n");
  ASSERT_TRUE(l.ok) << l.errors;
  EXPECT_EQ(l.cfg.service.stall_timeout_ms, 1000u);
  EXPECT_EQ(l.cfg.service.stop_timeout_ms, 1500u);
}

TEST(ServiceConfig, RangesAndUnknownKeysAreNamed) {
  auto l = load("service:\n  stop_timeout_ms: 10\n  watchdog_sec: 3\n");
  EXPECT_FALSE(l.ok);
  EXPECT_NE(l.errors.find("service.stop_timeout_ms: 10 is outside"), std::string::npos) << l.errors;
  EXPECT_NE(l.errors.find("service.watchdog_sec"), std::string::npos) << l.errors;
}

TEST(ServiceConfig, StallTimeoutMustCoverTwoFullFieldScans) {
  // 1024x768 at 10 us dwell + 2 us flyback per line: 7.87 s per full field -> >= 15.73 s.
  auto l = load("governor: {initial_dwell_ns: 10000}\nservice: {stall_timeout_ms: 2000}\n");
  EXPECT_FALSE(l.ok);
  EXPECT_NE(l.errors.find("service.stall_timeout_ms: 2000 is below 15732 ms"), std::string::npos) << l.errors;
  l = load("governor: {initial_dwell_ns: 10000}\nservice: {stall_timeout_ms: 16000}\n");
  EXPECT_TRUE(l.ok) << l.errors;
}

TEST(ShippedConfigs, LoadWithoutErrors) {
  for (const char* rel : {"config/deploy/sempose.yaml", "config/deploy/examples/production.yaml", "config/default.yaml"}) {
    sempose::config::AppConfig cfg;
    std::string errors;
    EXPECT_TRUE(sempose::config::load_app_config(std::string(SEMPOSE_SOURCE_DIR) + "/" + rel, cfg, errors))
        << rel << ":\n" << errors;
    if (std::string(rel) == "config/deploy/examples/production.yaml") {
      EXPECT_EQ(cfg.pipeline.polling, "spin");
      EXPECT_TRUE(cfg.pipeline.strict_rt);
      EXPECT_EQ(cfg.can.interface, "can0");
    }
  }
}
