// The whole application's settings: one YAML file, one section per part of sempose.
// load_app_config reads every section with that part's reader and reports ALL problems
// (file:line: key: value: allowed range), unknown top-level sections included.
// Setup only (allocates); nothing here runs on an RT thread.
#pragma once

#include <string>
#include <vector>

#include "sempose/config/can_config.hpp"
#include "sempose/config/comedi_config.hpp"
#include "sempose/config/governor_config.hpp"
#include "sempose/config/gpio_config.hpp"
#include "sempose/config/pipeline_config.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/scan_config.hpp"
#include "sempose/config/service_config.hpp"
#include "sempose/config/sim_config.hpp"
#include "sempose/config/tracker_config.hpp"

namespace sempose::config {

struct AppConfig {
  std::string source = "sim";  // "sim" | "replay" | "comedi": which scan source `sempose run` uses
  ScanLimits scan;             // the scan generator (hal::ScanLimits)
  SimConfig sim;
  ReplayConfig replay;
  ComediConfig comedi;         // source: comedi (external scan through a DAQ card)
  std::vector<TargetConfig> targets;  // pattern file names resolved against the config's folder
  TrackerConfig tracker;
  GovernorConfig governor;
  PipelineConfig pipeline;
  OutputConfig output;
  CanConfig can;
  GpioConfig gpio;
  ServiceConfig service;        // systemd watchdog stall rule, SIGTERM drain bound
  std::string path;            // the file it was read from (for messages)
};

// The device node of the configured scan hardware ("" when frames come from the simulator or
// files): what a pre-flight check (sempose check-rt, a systemd unit) must find and may open.
inline std::string scan_device_path(const AppConfig& c) { return c.source == "comedi" ? c.comedi.device : ""; }

// Whether outputs that cannot be written on this machine, as this user, are config errors. A run
// refuses them; `check-rt` reads the config as the service would and reports them as one of its
// checks, beside the RT checks an engineer also needs to see (output_problems()).
enum class OutputCheck { kRefuse, kLeaveToCaller };

// Whether the config's targets (their files, and pipeline.schedule against them or the
// simulator's) are checked, or the caller gives other targets and checks them (`replay --pattern`).
enum class TargetCheck { kAgainstTheConfig, kLeaveToCaller };

// Reads and validates `path` into `out`. On failure returns false and error_text holds
// one line per problem; `out` then holds defaults plus whatever could be read.
bool load_app_config(const std::string& path, AppConfig& out, std::string& error_text,
                     OutputCheck outputs = OutputCheck::kRefuse, TargetCheck targets = TargetCheck::kAgainstTheConfig);
// The same for YAML text already in memory (tests, the fuzz target); `path` names it in
// messages and is the folder relative pattern paths resolve against.
bool parse_app_config(const std::string& text, const std::string& path, AppConfig& out,
                      std::string& error_text, OutputCheck outputs = OutputCheck::kRefuse);

// The configured outputs (poses CSV, candump log, histogram folder) that cannot be written here
// by this user: the key and the problem ("'/var/log/x.csv' cannot be written: it is ...").
struct OutputProblem {
  std::string key;
  std::string what;
};
std::vector<OutputProblem> output_problems(const AppConfig& c);
// The top-level keys `sempose run` reads (source, scan, sim, ...), in the order it reads them:
// `sempose sim` reads only scan: and sim: from a run's config but must still refuse a key no
// part of sempose knows (a typo such as `sim_targets:` ran the default scene).
const std::vector<std::string>& app_config_sections();
// Every scalar key the readers look at for this text (lists as far as the text has items),
// with its kind: what the table-driven tests iterate over.
std::vector<KeyInfo> config_keys(const std::string& text);

}  // namespace sempose::config
