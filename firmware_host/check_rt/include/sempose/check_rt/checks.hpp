// The RT preflight: one result per check (pass / warn / fail), each failing or warning one
// with the fix a lab engineer applies. What is checked follows the config: its RT cores,
// priorities, polling mode, memory locking, DMA-latency hold, CAN interface, GPIO lines and
// scan source.
//
// Levels: fail = the RT guarantee cannot hold (or sempose cannot start) as configured;
// warn = it holds but with a known latency risk. A spinning configuration (polling: spin)
// turns the isolation and RT-throttling warnings into failures: a spinning FIFO thread on a
// shared, throttled core stalls for 50 ms every second.
#pragma once

#include <string>
#include <vector>

#include "sempose/check_rt/live_probe.hpp"
#include "sempose/check_rt/system_tree.hpp"
#include "sempose/config/app_config.hpp"

namespace sempose::check_rt {

enum class Level { kPass, kWarn, kFail };

struct CheckResult {
  std::string name;    // short id: kernel, isolcpus, ...
  Level level = Level::kPass;
  std::string detail;  // what was found
  std::string fix;     // what to do (empty when passing)
};

std::vector<CheckResult> run_checks(const SystemTree& tree, const config::AppConfig& cfg, LiveProbe& probe);

// "PASS  kernel       PREEMPT_RT kernel ...", "FAIL  ... -- fix: ..."
std::string format_result(const CheckResult& r);
// 0: all pass; 1: warnings only; 3: at least one failure (2 stays for usage/config errors).
int exit_code(const std::vector<CheckResult>& results);
const char* to_string(Level level);

}  // namespace sempose::check_rt
