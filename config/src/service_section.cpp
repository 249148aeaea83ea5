#include <string>

#include "sempose/config/reader.hpp"
#include "sempose/config/scan_config.hpp"
#include "sempose/config/service_config.hpp"

namespace sempose::config {

void read_service(Section& s, ServiceConfig& c) {
  s.opt("stall_timeout_ms", c.stall_timeout_ms, 50u, 600'000u);
  s.opt("stop_timeout_ms", c.stop_timeout_ms, 100u, 600'000u);
}

std::string stall_timeout_problem(const ServiceConfig& service, const ScanLimits& scan, std::uint32_t initial_dwell_ns) {
  const std::int64_t full_field_ns = scan.scan_time_ns(scan.field_w, scan.field_h, initial_dwell_ns);
  const std::int64_t needed_ms = (2 * full_field_ns + 999'999) / 1'000'000;
  if (static_cast<std::int64_t>(service.stall_timeout_ms) >= needed_ms) return "";
  return std::to_string(service.stall_timeout_ms) + " is below " + std::to_string(needed_ms) +
         " ms, twice the full-field scan at governor.initial_dwell_ns (" + std::to_string(scan.field_w) + "x" +
         std::to_string(scan.field_h) + " px at " + std::to_string(initial_dwell_ns) +
         " ns): a start search would count as a stall";
}

void check_service_against_scan(Section& root, const ServiceConfig& service, const ScanLimits& scan,
                                std::uint32_t initial_dwell_ns) {
  if (const std::string why = stall_timeout_problem(service, scan, initial_dwell_ns); !why.empty()) {
    root.error_at("service.stall_timeout_ms", why);
  }
}

}  // namespace sempose::config
