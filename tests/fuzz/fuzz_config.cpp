// libFuzzer target: the config loader from YAML text (parse, every section reader, range and
// cross-section checks). Any text must give a config or named errors, never an escaping
// exception, a crash or undefined behaviour.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "sempose/config/app_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  sempose::config::AppConfig cfg;
  std::string errors;
  const bool ok = sempose::config::parse_app_config(text, "/nonexistent-fuzz-dir/fuzz.yaml", cfg, errors);
  if (ok != errors.empty()) std::abort();  // accepted exactly when no error was reported
  if (ok) {
    // An accepted config holds only finite values in the ranges downstream code relies on.
    const auto& t = cfg.tracker;
    if (!(t.pattern_size_px >= 8 && t.pattern_size_px <= t.roi_size_px && t.roi_size_px <= 1024)) std::abort();
    if (!std::isfinite(t.score_threshold) || !std::isfinite(cfg.governor.margin) ||
        !std::isfinite(cfg.sim.beam_current_pa) || !std::isfinite(cfg.can.heartbeat_hz)) {
      std::abort();
    }
    if (cfg.scan.min_dwell_ns > cfg.scan.max_dwell_ns || cfg.scan.field_w < 16 || cfg.scan.field_h < 16) std::abort();
  }
  return 0;
}
