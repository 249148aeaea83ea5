// Builds the configured scan source at setup: kind "sim" (simulated SEM), "replay"
// (recorded frames) or "comedi" (external scan through a Comedi DAQ card). Allocates everything the source needs; returns nullptr and a status
// naming the problem (file, key, value) when it cannot.
#pragma once

#include <memory>
#include <string>

#include "sempose/config/comedi_config.hpp"
#include "sempose/config/sim_config.hpp"
#include "sempose/hal/scan_source.hpp"
#include "sempose/rt/result.hpp"

namespace sempose::hal {

std::unique_ptr<ScanSource> make_scan_source(const std::string& kind, const ScanLimits& limits,
                                             const config::SimConfig& sim, const config::ReplayConfig& replay,
                                             rt::Status& status,
                                             const config::ComediConfig& comedi = {});

}  // namespace sempose::hal
