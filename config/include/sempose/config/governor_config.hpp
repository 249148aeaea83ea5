// Settings of the adaptive scan-speed governor (firmware_host/pipeline ScanSpeedGovernor):
// it picks the pixel dwell of the next ROI so that its scan time ≈ the robust recent compute
// time per pose × (1 + margin), lengthened when match quality falls, within dwell limits.
#pragma once

#include <cstdint>

#include "sempose/config/reader.hpp"
#include "sempose/config/scan_config.hpp"

namespace sempose::config {

struct GovernorConfig {
  bool enabled = true;                 // false: every ROI is scanned at initial_dwell_ns
  std::uint32_t initial_dwell_ns = 250;  // before the first compute time is known
  std::uint32_t min_dwell_ns = 0;      // 0: the scan generator's min_dwell_ns
  std::uint32_t max_dwell_ns = 0;      // 0: the scan generator's max_dwell_ns
  double margin = 0.2;                 // scan time = compute estimate × (1 + margin)
  double percentile = 0.8;             // high percentile of the recent compute times...
  std::uint32_t window = 10;           // ...over this many poses...
  double ewma_alpha = 0.5;             // ...smoothed by an EWMA when falling (rises are taken at once)
  double hysteresis = 0.08;            // relative band: shorter dwells are taken only below it
  double max_decrease_per_frame = 0.15; // a falling dwell shrinks at most this fraction per pose
  // Match quality: below these the dwell is lengthened (cleaner image), recovering above
  // them plus the hysteresis band.
  float low_score = 0.5f;
  float low_psr = 0.0f;                // 0: PSR not used
  double quality_gain = 1.25;          // dwell factor per low-quality pose
  double max_quality_factor = 4.0;     // cap of the accumulated quality factor
  double min_pose_rate_hz = 10.0;      // per target: the dwell never drops the pose rate below this
  bool min_pose_rate_given = false;    // min_pose_rate_hz came from the config (checked against the scan)
  bool initial_dwell_given = false;    // initial_dwell_ns came from the config (checked against min/max)
};

// Reads the `governor:` section (config/src/governor_section.cpp).
void read_governor(Section& section, GovernorConfig& out);

// The governor's own dwell limits must overlap the scan's: a governor.min_dwell_ns above
// scan.max_dwell_ns left every scan request refused (exit 0 with no frame, or a "stall"), and
// a governor.max_dwell_ns below scan.min_dwell_ns was raised to it without a word.
void check_governor_against_scan(Section& root, const GovernorConfig& governor, const ScanLimits& scan);

}  // namespace sempose::config
