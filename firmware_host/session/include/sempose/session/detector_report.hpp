// The detector lines of `sempose run`'s and `sempose replay`'s report, one target's: τ measured
// from the frames (what to configure once known), told τ checked against them, and frames whose
// lag against the pattern was beyond what sempose corrects (their poses UNCERTAIN).
#pragma once

#include <cstdio>
#include <string>

#include "sempose/pose/tracker.hpp"

namespace sempose::session {

void print_detector_report(std::FILE* out, int target, const std::string& name, const pose::Tracker::DetectorTauStatus& d);

}  // namespace sempose::session
