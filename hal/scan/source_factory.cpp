#include "sempose/hal/source_factory.hpp"

#include <exception>

#include "sempose/hal/comedi_scan_source.hpp"
#include "sempose/hal/replay_source.hpp"
#include "sempose/hal/sim_source.hpp"

namespace sempose::hal {

std::unique_ptr<ScanSource> make_scan_source(const std::string& kind, const ScanLimits& limits,
                                             const config::SimConfig& sim, const config::ReplayConfig& replay,
                                             rt::Status& status, const config::ComediConfig& comedi) {
  try {
    if (kind == "sim") {
      status = rt::Status::success();
      return std::make_unique<SimSource>(limits, sim);
    }
    if (kind == "replay") {
      if (replay.frames_dir.empty()) {
        status = rt::Status::failure("replay.frames_dir: not set (a directory of PGM frames, e.g. from `sempose sim --out DIR`)");
        return nullptr;
      }
      status = rt::Status::success();
      return std::make_unique<ReplaySource>(limits, replay);
    }
    if (kind == "comedi") {
      status = rt::Status::success();
      return std::make_unique<ComediScanSource>(limits, comedi);
    }
    status = rt::Status::failure("scan source '" + kind + "' is not one of: sim, replay, comedi");
  } catch (const std::exception& e) {
    status = rt::Status::failure(std::string(kind == "sim" ? "simulated SEM: " : kind == "comedi" ? "" : "replay: ") + e.what());
  }
  return nullptr;
}

}  // namespace sempose::hal
