// How sempose behaves as a system service (YAML section `service:`): when the pipeline
// counts as stalled (the systemd watchdog is fed only while it is not, and the CAN
// heartbeat reports it) and how long a SIGTERM drain may take before the process gives up
// on the stages and exits anyway.
#pragma once

#include <cstdint>
#include <string>

namespace sempose::config {

class Section;
struct ScanLimits;

struct ServiceConfig {
  // A running stage that has not advanced its counter (frames scanned, poses made, poses
  // published) for this long is stalled. Must exceed the longest scan the pipeline starts:
  // the full-field start search at governor.initial_dwell_ns.
  std::uint32_t stall_timeout_ms = 2000;
  // SIGTERM/SIGINT: the stages finish the frames in flight; after this long sempose writes
  // what it has and exits with code 4 (systemd's TimeoutStopSec must be longer).
  std::uint32_t stop_timeout_ms = 5000;
};

// Reads `service:` (config/src/service_section.cpp).
void read_service(Section& section, ServiceConfig& out);

// service.stall_timeout_ms against the longest scan: a full field at initial_dwell_ns must
// fit twice, or a healthy start search would be reported as a stall.
void check_service_against_scan(Section& root, const ServiceConfig& service, const ScanLimits& scan,
                                std::uint32_t initial_dwell_ns);
// The same rule for a field known only once the source is open (a recording's frames set it):
// "" when it holds, else the problem (for "service.stall_timeout_ms: ...").
std::string stall_timeout_problem(const ServiceConfig& service, const ScanLimits& scan, std::uint32_t initial_dwell_ns);

}  // namespace sempose::config
