// Helpers for the hal scan tests: temp dirs and simulator configs with every artefact off.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <random>
#include <string>

#include "sempose/config/sim_config.hpp"

namespace sempose::hal::test {

inline std::filesystem::path temp_dir(const std::string& name) {
  const auto p = std::filesystem::temp_directory_path() /
                 ("sempose_hal_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

// A flat black scene, no noise and no artefacts: what remains is pure geometry.
inline config::SimConfig clean_config() {
  config::SimConfig c;
  c.clock = "virtual";
  c.noise = false;
  c.psf_sigma_px = 0;
  c.line_jitter_px = 0;
  c.beam_lag_px = 0;
  c.drift.clear();
  c.brightness_drift = 0;
  c.background.mean = 0;
  c.background.contrast = 0;
  c.targets.clear();
  return c;
}

}  // namespace sempose::hal::test
