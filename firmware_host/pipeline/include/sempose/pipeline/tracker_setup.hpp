// Setup-time wiring of the trackers from the application config: one pose::Tracker per
// target, with its pattern sets read from PGM files (targets: ...), or, on the simulated SEM
// without a targets: list, patterns recorded from the simulator itself (one per enabled sim
// target, averaged like an operator would record them). Allocates; never on an RT thread.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "sempose/config/app_config.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/rt/result.hpp"

namespace sempose::pose {
class Tracker;
struct PatternSet;
}

namespace sempose::pipeline {

struct TrackerSetup {
  std::vector<std::unique_ptr<pose::Tracker>> trackers;  // index = target
  std::vector<std::string> names;
  std::vector<std::string> pattern_origins;  // "file.pgm" or "simulator target 0"
  std::size_t memory_bytes = 0;              // banks + spectra + FFT buffers, all targets
  std::vector<std::string> warnings;         // the trackers' setup warnings ("target NAME: …")
  // One line per pattern set that looks the same turned (pose::PatternSymmetry, order > 1): the
  // startup log tells the operator that its target's angle is known modulo 360°/order.
  std::vector<std::string> symmetry_notes;
  TrackerSetup();
  ~TrackerSetup();
  TrackerSetup(TrackerSetup&&) noexcept;
  TrackerSetup& operator=(TrackerSetup&&) noexcept;
};

// Reads one pattern set's PGM files (pattern, optional shape mask); the error names the file.
rt::Status load_pattern_set(const config::PatternSetConfig& cfg, pose::PatternSet& out);

rt::Status make_trackers(const config::AppConfig& cfg, const hal::ScanLimits& limits, TrackerSetup& out);

}  // namespace sempose::pipeline
