#include "sempose/check_rt/checks.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdint>
#include <charconv>
#include <filesystem>
#include <optional>
#include <set>
#include <utility>
#include <sstream>

namespace sempose::check_rt {
namespace {

constexpr int kCapIpcLock = 14;  // linux/capability.h
constexpr int kCapSysNice = 23;

CheckResult pass(std::string name, std::string detail) { return {std::move(name), Level::kPass, std::move(detail), {}}; }
CheckResult warn(std::string name, std::string detail, std::string fix) {
  return {std::move(name), Level::kWarn, std::move(detail), std::move(fix)};
}
CheckResult fail(std::string name, std::string detail, std::string fix) {
  return {std::move(name), Level::kFail, std::move(detail), std::move(fix)};
}
CheckResult risk(bool severe, std::string name, std::string detail, std::string fix) {
  return severe ? fail(std::move(name), std::move(detail), std::move(fix)) : warn(std::move(name), std::move(detail), std::move(fix));
}

// The cores the config pins RT stages to (output only when it has its own thread).
std::vector<int> rt_cpus(const config::PipelineConfig& p) {
  std::set<int> s;
  for (const auto* st : {&p.acquisition, &p.correlation}) {
    if (st->cpu >= 0) s.insert(st->cpu);
  }
  if (!p.output_on_correlation_thread && p.output.cpu >= 0) s.insert(p.output.cpu);
  return {s.begin(), s.end()};
}

// A whole number in digits only, as the kernel writes its files (base 16 for capability masks):
// "", "-1", " 12", "4000zz", "1e6" and anything past 64 bits are none (hostile round 9 found each
// of these read as some number by hand-made parsers).
std::optional<std::uint64_t> whole_number(const std::string& text, int base = 10) {
  std::uint64_t n = 0;
  const char* end = text.data() + text.size();
  const auto [at, error] = std::from_chars(text.data(), end, n, base);
  if (text.empty() || error != std::errc{} || at != end) return std::nullopt;
  return n;
}

int max_priority(const config::PipelineConfig& p) {
  int m = std::max(p.acquisition.priority, p.correlation.priority);
  if (!p.output_on_correlation_thread) m = std::max(m, p.output.priority);
  return m;
}

std::vector<int> missing_from(const std::vector<int>& want, const std::vector<int>& have) {
  std::vector<int> out;
  for (int c : want) {
    if (!std::binary_search(have.begin(), have.end(), c)) out.push_back(c);
  }
  return out;
}

// A boot parameter's value as the kernel takes it: quotes dropped (`key="v"`, `"key=v"`), and
// the last of several (each one parses over the one before; the first was read, a false PASS).
std::optional<std::string> cmdline_value(const std::string& cmdline, const std::string& key) {
  std::istringstream ss(cmdline);
  std::string word;
  std::optional<std::string> value;
  while (ss >> word) {
    if (word == "--") break;  // what follows goes to init, not the kernel
    word.erase(std::remove(word.begin(), word.end(), '"'), word.end());
    if (word.rfind(key + "=", 0) == 0) value = word.substr(key.size() + 1);
  }
  return value;
}

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n"), e = s.find_last_not_of(" \t\r\n");
  return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

// The cores whose RCU callbacks are offloaded: rcu_nocbs= (a list, or "all"), and every
// nohz_full core, which the kernel offloads itself (rcu_init_nohz()): a box booted with
// nohz_full alone was told to add rcu_nocbs.
std::vector<int> rcu_offloaded(const std::string& cmdline, const std::vector<int>& online, const std::vector<int>& nohz_full) {
  std::set<int> cores(nohz_full.begin(), nohz_full.end());
  if (const auto v = cmdline_value(cmdline, "rcu_nocbs")) {
    // "N" is the last CPU; a list the kernel cannot parse makes it offload every CPU ("bad CPU
    // range, all CPUs set"); the group form ("0-7:1/2") is read as the kernel reads it.
    std::string list = *v;
    const std::string last = online.empty() ? "0" : std::to_string(online.back());
    for (std::size_t at = list.find('N'); at != std::string::npos; at = list.find('N', at)) list.replace(at, 1, last);
    const auto parsed = list == "all" ? std::optional<std::vector<int>>(online) : parse_cpu_list(list);
    const std::vector<int> listed = parsed.value_or(online);
    cores.insert(listed.begin(), listed.end());
  }
  return {cores.begin(), cores.end()};
}

// A field of /proc/self/status ("CapEff:\t000001ffffffffff").
std::string status_field(const SystemTree& tree, const std::string& field) {
  const auto text = tree.read("proc/self/status");
  if (!text) return {};
  std::istringstream ss(*text);
  std::string line;
  while (std::getline(ss, line)) {
    if (line.rfind(field + ":", 0) == 0) {
      std::string v = line.substr(field.size() + 1);
      v.erase(0, v.find_first_not_of(" \t"));
      return v;
    }
  }
  return {};
}

bool has_capability(const SystemTree& tree, int cap) {
  // 16 hex digits as the kernel writes them; anything else is not read as held ("-1" wrapped to
  // every capability, "4000zz" was read as 4000; hostile round 9).
  const auto eff = whole_number(trimmed(status_field(tree, "CapEff")), 16);
  return eff && ((*eff >> cap) & 1u);
}

// Soft limit of a /proc/self/limits row ("Max locked memory  8388608  8388608  bytes").
std::string soft_limit(const SystemTree& tree, const std::string& row) {
  const auto text = tree.read("proc/self/limits");
  if (!text) return {};
  std::istringstream ss(*text);
  std::string line;
  while (std::getline(ss, line)) {
    if (line.rfind(row, 0) == 0) {
      std::istringstream rest(line.substr(row.size()));
      std::string soft;
      rest >> soft;
      return soft;
    }
  }
  return {};
}

std::string isolation_fix(const std::vector<int>& cpus) {
  const std::string l = format_cpu_list(cpus);
  return "add 'isolcpus=" + l + " nohz_full=" + l + " rcu_nocbs=" + l +
         "' to GRUB_CMDLINE_LINUX in /etc/default/grub, run update-grub and reboot";
}

void check_kernel(const SystemTree& tree, std::vector<CheckResult>& out) {
  const std::string release = tree.read("proc/sys/kernel/osrelease").value_or("?");
  const std::string version = tree.read("proc/sys/kernel/version").value_or("");
  const bool rt = tree.read("sys/kernel/realtime").value_or("") == "1" || version.find("PREEMPT_RT") != std::string::npos;
  if (rt) out.push_back(pass("kernel", "PREEMPT_RT kernel " + release));
  else
    out.push_back(fail("kernel", "kernel " + release + " is not PREEMPT_RT (" + (version.empty() ? "?" : version) + ")",
                       "apt-get install linux-image-rt-amd64 and boot it (uname -v then shows PREEMPT_RT)"));
}

void check_cpus(const std::vector<int>& rt, const std::vector<int>& online,
                std::vector<CheckResult>& out) {
  if (rt.empty()) {
    out.push_back(warn("rt-cpus", "no RT stage is pinned (pipeline.*.cpu = -1)",
                       "pin acquisition and correlation to cores of their own in pipeline: (e.g. acquisition: {cpu: 2})"));
    return;
  }
  const auto gone = missing_from(rt, online);
  if (!gone.empty()) {
    out.push_back(fail("rt-cpus", "RT core(s) " + format_cpu_list(gone) + " not online (online: " + format_cpu_list(online) + ")",
                       "set pipeline.acquisition/correlation/output.cpu to online cores"));
    return;
  }
  const auto housekeeping = missing_from(online, rt);
  if (housekeeping.empty()) {
    out.push_back(warn("rt-cpus", "RT cores " + format_cpu_list(rt) + " are every online core: nothing left for the kernel and the non-RT thread",
                       "leave at least one core (usually 0) out of pipeline.*.cpu"));
    return;
  }
  out.push_back(pass("rt-cpus", "RT cores " + format_cpu_list(rt) + ", housekeeping " + format_cpu_list(housekeeping)));
}

void check_isolation(const SystemTree& tree, const std::vector<int>& rt, const std::vector<int>& online, bool spin,
                     std::vector<CheckResult>& out) {
  if (rt.empty()) return;
  const std::string cmdline = tree.read("proc/cmdline").value_or("");
  const auto nohz_full = parse_cpu_list(tree.read("sys/devices/system/cpu/nohz_full").value_or("")).value_or(std::vector<int>{});
  struct Source {
    const char* name;
    std::vector<int> cpus;
    const char* why;
  };
  const Source sources[] = {
      {"isolcpus", parse_cpu_list(tree.read("sys/devices/system/cpu/isolated").value_or("")).value_or(std::vector<int>{}),
       "the scheduler still puts other tasks there"},
      {"nohz_full", nohz_full, "the scheduler tick still interrupts them"},
      {"rcu_nocbs", rcu_offloaded(cmdline, online, nohz_full), "RCU callbacks still run there"},
  };
  for (const auto& s : sources) {
    const auto missing = missing_from(rt, s.cpus);
    if (missing.empty()) out.push_back(pass(s.name, "RT cores " + format_cpu_list(rt) + " covered"));
    else
      out.push_back(risk(spin, s.name, "RT core(s) " + format_cpu_list(missing) + " not in " + s.name + ": " + s.why,
                         isolation_fix(rt)));
  }
}

void check_throttling(const SystemTree& tree, bool spin, std::vector<CheckResult>& out) {
  const auto runtime = tree.read("proc/sys/kernel/sched_rt_runtime_us");
  const auto period = tree.read("proc/sys/kernel/sched_rt_period_us");
  const std::string value = runtime ? trimmed(*runtime) : "";
  const std::string fix = "sysctl -w kernel.sched_rt_runtime_us=-1 and persist it: echo 'kernel.sched_rt_runtime_us = -1' > "
                          "/etc/sysctl.d/60-sempose.conf";
  // A whole number as the kernel writes it ("abc" or "" was reported as "RT threads get abc of
  // every … us", "00" as some RT time; hostile round 9).
  const bool negative = !value.empty() && value[0] == '-';
  const auto magnitude = whole_number(negative ? value.substr(1) : value);
  const bool number = magnitude && *magnitude <= std::uint64_t{1} << 62;
  const long long us = number ? (negative ? -1 : 1) * static_cast<long long>(*magnitude) : 0;
  if (!runtime || !number) {
    out.push_back(warn("rt-throttling",
                       runtime ? "/proc/sys/kernel/sched_rt_runtime_us holds '" + value + "', not a number: RT throttling not checked"
                               : "cannot read /proc/sys/kernel/sched_rt_runtime_us",
                       "check that /proc is mounted (check-rt --root: that the tree's file holds a number such as -1)"));
  } else if (us < 0) {
    out.push_back(pass("rt-throttling", "off (sched_rt_runtime_us = " + value + ")"));
  } else if (us == 0) {
    // No RT time at all: a SCHED_FIFO stage never runs (it was only a WARN).
    out.push_back(fail("rt-throttling", "RT threads get no time at all (sched_rt_runtime_us = 0): the FIFO stages cannot run", fix));
  } else {
    out.push_back(risk(spin, "rt-throttling",
                       "on: RT threads get " + value + " of every " + trimmed(period.value_or("?")) +
                           " us; a busy FIFO thread is paused for the rest",
                       fix));
  }
}

void check_governor(const SystemTree& tree, const std::vector<int>& rt, std::vector<CheckResult>& out) {
  std::vector<int> slow, unread;
  std::vector<std::pair<std::string, std::vector<int>>> seen;  // each slow governor and its cores
  bool any_cpufreq = false;
  for (int c : rt) {
    const std::string dir = "sys/devices/system/cpu/cpu" + std::to_string(c) + "/cpufreq";
    const auto g = tree.read(dir + "/scaling_governor");
    if (!g) {
      // A cpufreq folder whose governor cannot be read is not "no frequency scaling" (it passed
      // as such; hostile round 9).
      if (tree.exists(dir)) unread.push_back(c);
      continue;
    }
    any_cpufreq = true;
    if (*g != "performance") {
      slow.push_back(c);
      auto it = std::find_if(seen.begin(), seen.end(), [&](const auto& e) { return e.first == *g; });
      if (it == seen.end()) it = seen.insert(seen.end(), {*g, {}});
      it->second.push_back(c);
    }
  }
  // No cpufreq folder is a fixed clock (or a VM) only where the cores' folder is there at all.
  if (!any_cpufreq && !rt.empty() && !tree.exists("sys/devices/system/cpu")) {
    out.push_back(warn("cpufreq", "cannot read /sys/devices/system/cpu: frequency scaling of the RT cores not checked",
                       "run on a Linux system with /sys mounted"));
  } else if (!slow.empty() || !unread.empty()) {
    // Both are said when both are there (an unread core was not named beside a slow one).
    const std::string unread_text = unread.empty() ? "" : "cannot read the scaling governor of RT core(s) " + format_cpu_list(unread) +
                                                              ": frequency scaling not checked there";
    const std::string unread_fix = "check that /sys is the kernel's own (check-rt --root: a file scaling_governor holding e.g. performance)";
    if (slow.empty()) {
      out.push_back(warn("cpufreq", unread_text, unread_fix));
    } else {
      // Each governor with its own cores (only the last one read was named, for every slow core).
      std::string governors;
      for (const auto& [name, cores] : seen)
        governors += (governors.empty() ? "'" : ", '") + name + "' on RT core(s) " + format_cpu_list(cores);
      out.push_back(warn("cpufreq",
                         "governor " + governors + ": clock ramps add latency" + (unread.empty() ? "" : "; " + unread_text),
                         "cpupower frequency-set -c " + format_cpu_list(slow) + " -g performance (package linux-cpupower)" +
                             (unread.empty() ? "" : "; " + unread_fix)));
    }
  } else if (!any_cpufreq) {
    out.push_back(pass("cpufreq", "no frequency scaling on the RT cores (fixed clock or VM)"));
  } else {
    out.push_back(pass("cpufreq", "performance on RT cores " + format_cpu_list(rt)));
  }
}

void check_dma_latency(const SystemTree& tree, const config::PipelineConfig& p, std::vector<CheckResult>& out) {
  if (!p.hold_dma_latency) {
    out.push_back(pass("cpu-dma-latency", "not used (pipeline.hold_dma_latency: false)"));
  } else if (!tree.exists("dev/cpu_dma_latency")) {
    out.push_back(fail("cpu-dma-latency", "/dev/cpu_dma_latency missing", "a kernel with PM QoS (every Debian kernel) and /dev mounted"));
  } else if (!tree.writable("dev/cpu_dma_latency")) {
    out.push_back(fail("cpu-dma-latency", "/dev/cpu_dma_latency not writable: deep C-states stay allowed",
                       "install the package's udev rule (group sempose, mode 0660) and run as user sempose, or as root"));
  } else {
    out.push_back(pass("cpu-dma-latency", "/dev/cpu_dma_latency writable"));
  }
}

void check_irqs(const SystemTree& tree, const std::vector<int>& rt, const std::vector<int>& online,
                std::vector<CheckResult>& out) {
  if (rt.empty()) return;
  const auto housekeeping = missing_from(online, rt);
  std::vector<std::string> on_rt, unparsed;  // unparsed: what cannot be read is not passed
  int movable = 0;
  for (const std::string& irq : tree.list("proc/irq")) {
    if (irq.empty() || !std::all_of(irq.begin(), irq.end(), ::isdigit)) continue;
    const auto list = tree.read("proc/irq/" + irq + "/smp_affinity_list");
    ++movable;
    // Unread or empty (no CPU, which no IRQ has) is not checked, and said: every list a
    // directory or empty passed as "none may run on RT cores" (hostile round 9).
    const auto cpus = list ? parse_cpu_list(*list) : std::nullopt;
    if (!cpus || cpus->empty()) {
      unparsed.push_back("/proc/irq/" + irq + "/smp_affinity_list");
      continue;
    }
    if (missing_from(rt, *cpus).size() < rt.size()) on_rt.push_back(irq);
  }
  const auto def = tree.read("proc/irq/default_smp_affinity");
  const auto def_cpus = def ? parse_cpu_mask(*def) : std::nullopt;
  if (def && !def_cpus) unparsed.push_back("/proc/irq/default_smp_affinity");
  const bool default_on_rt = def_cpus && missing_from(rt, *def_cpus).size() < rt.size();
  const std::string hk = housekeeping.empty() ? "0" : format_cpu_list(housekeeping);
  const std::string fix = "boot with irqaffinity=" + hk + ", or: for f in /proc/irq/*/smp_affinity_list; do echo " + hk +
                          " > $f; done";
  if (movable == 0 && !def) {
    // Nothing read: not "none on the RT cores" (found probing: an empty tree passed).
    out.push_back(warn("irq-affinity", "cannot read /proc/irq: IRQ affinity not checked", "run on a Linux system with /proc mounted"));
  } else if (on_rt.empty() && !default_on_rt && unparsed.empty()) {
    out.push_back(pass("irq-affinity", std::to_string(movable) + " IRQs, none may run on RT cores " + format_cpu_list(rt)));
  } else if (on_rt.empty() && !default_on_rt) {
    out.push_back(warn("irq-affinity",
                       "cannot parse " + unparsed.front() + (unparsed.size() > 1 ? " and " + std::to_string(unparsed.size() - 1) + " more" : "") +
                           ": those IRQs not checked",
                       "check that /proc is the kernel's own (check-rt --root: that the tree's files hold CPU lists such as 0-1)"));
  } else {
    std::string which;
    for (std::size_t i = 0; i < on_rt.size() && i < 8; ++i) which += (i ? "," : "") + on_rt[i];
    if (on_rt.size() > 8) which += ",...";
    out.push_back(warn("irq-affinity",
                       std::to_string(on_rt.size()) + " of " + std::to_string(movable) + " IRQs may run on RT cores " +
                           format_cpu_list(rt) + (which.empty() ? "" : " (" + which + ")") +
                           (default_on_rt ? "; new IRQs default there too" : ""),
                       fix));
  }
}

void check_limits(const SystemTree& tree, const config::PipelineConfig& p, std::vector<CheckResult>& out) {
  const bool root_or_cap_lock = has_capability(tree, kCapIpcLock);
  const std::string memlock = soft_limit(tree, "Max locked memory");
  if (!p.lock_memory) {
    out.push_back(pass("memlock", "not used (pipeline.lock_memory: false)"));
  } else if (root_or_cap_lock || memlock == "unlimited") {
    out.push_back(pass("memlock", root_or_cap_lock ? "CAP_IPC_LOCK held" : "limit unlimited"));
  } else if (whole_number(memlock).value_or(0) >= (std::uint64_t{1} << 30)) {
    // A large number (LimitMEMLOCK=4G) may hold the whole process, or may not: mlockall locks all
    // of it (banks, FFT plans, the frame pool, every stack), which this check does not measure.
    // It used to FAIL whatever the size (hostile round 9); `sempose run` says whether it locked.
    out.push_back(warn("memlock", "locked-memory limit " + memlock + " bytes and no CAP_IPC_LOCK: mlockall succeeds only "
                                      "if the whole process fits (sempose run says at start whether it locked)",
                       "LimitMEMLOCK=infinity in the unit (the package's sempose.service has it), or AmbientCapabilities=CAP_IPC_LOCK"));
  } else {
    out.push_back(fail("memlock", "locked-memory limit " + (memlock.empty() ? std::string("?") : memlock + " bytes") +
                                      " and no CAP_IPC_LOCK: mlockall fails, pages can be swapped out",
                       "LimitMEMLOCK=infinity in the unit (the package's sempose.service has it), or AmbientCapabilities=CAP_IPC_LOCK"));
  }
  const int want = max_priority(p);
  const bool cap_nice = has_capability(tree, kCapSysNice);
  const std::string rtprio = soft_limit(tree, "Max realtime priority");
  // A limit above 99 allows 99 (4294967296 used to overflow stoi and read as 0, "below the
  // configured 60"; hostile round 9); anything but a number is no limit read.
  const int limit = rtprio == "unlimited" ? 99 : static_cast<int>(std::min<std::uint64_t>(whole_number(rtprio).value_or(0), 99));
  if (want == 0) {
    out.push_back(pass("rtprio", "no SCHED_FIFO stage configured (priorities 0)"));
  } else if (cap_nice || limit >= want) {
    out.push_back(pass("rtprio", std::string(cap_nice ? "CAP_SYS_NICE held" : "limit " + rtprio) + ", SCHED_FIFO up to " +
                                     std::to_string(want) + " and pinning allowed"));
  } else {
    out.push_back(fail("rtprio", "RT priority limit " + (rtprio.empty() ? std::string("?") : rtprio) +
                                     " below the configured " + std::to_string(want) + " and no CAP_SYS_NICE",
                       "LimitRTPRIO=" + std::to_string(want) + " in the unit, or AmbientCapabilities=CAP_SYS_NICE"));
  }
}

void check_can(const SystemTree& tree, const config::CanConfig& c, LiveProbe& probe, std::vector<CheckResult>& out) {
  if (c.interface.empty()) {
    out.push_back(pass("can", "no CAN interface configured (frames go to the candump log " + c.log_file + ")"));
    return;
  }
  const std::string dir = "sys/class/net/" + c.interface;
  if (!tree.exists(dir)) {
    out.push_back(fail("can", "no network interface '" + c.interface + "'",
                       "load the controller's driver (or 'ip link add dev " + c.interface + " type vcan' for tests)"));
    return;
  }
  if (tree.read(dir + "/type").value_or("") != "280") {
    out.push_back(fail("can", "'" + c.interface + "' is not a CAN interface (type " + tree.read(dir + "/type").value_or("?") + ")",
                       "set can.interface to a SocketCAN interface (ip -details link show)"));
    return;
  }
  const std::string bitrate_arg = c.bitrate ? std::to_string(c.bitrate) : std::string("1000000");
  // The kernel writes the flags as "0x40c1"; anything else reads as down.
  const std::string flags_text = trimmed(tree.read(dir + "/flags").value_or(""));
  const auto flags = whole_number(flags_text.rfind("0x", 0) == 0 ? flags_text.substr(2) : flags_text, 16);
  if ((flags.value_or(0) & 0x1u) == 0) {
    out.push_back(fail("can", "'" + c.interface + "' is down",
                       "ip link set " + c.interface + " type can bitrate " + bitrate_arg + " && ip link set " + c.interface + " up"));
    return;
  }
  const auto d = probe.can_link(c.interface);
  if (!d) {
    out.push_back(pass("can", "'" + c.interface + "' up (controller details not available)"));
    return;
  }
  if (d->kind == "vcan") {
    out.push_back(pass("can", "'" + c.interface + "' up (vcan: virtual, no bitrate or bus state)"));
    return;
  }
  const std::string what = "'" + c.interface + "' up, " + (d->bitrate ? std::to_string(d->bitrate) + " bit/s" : "no bitrate") +
                           ", " + (d->state.empty() ? "state ?" : d->state);
  if (d->state == "bus-off" || d->state == "stopped") {
    out.push_back(fail("can", what, "check wiring and termination, then: ip link set " + c.interface + " down && ip link set " +
                                        c.interface + " up (or ip link set " + c.interface + " type can restart-ms 100)"));
  } else if (c.bitrate != 0 && d->bitrate != c.bitrate) {
    out.push_back(warn("can", what + ", config says can.bitrate " + std::to_string(c.bitrate),
                       "ip link set " + c.interface + " down && ip link set " + c.interface + " type can bitrate " +
                           std::to_string(c.bitrate) + " && ip link set " + c.interface + " up"));
  } else if (d->state == "error-passive" || d->state == "error-warning") {
    out.push_back(warn("can", what, "errors on the bus: check wiring, termination and the other nodes' bitrate"));
  } else {
    out.push_back(pass("can", what));
  }
}

void check_gpio(const config::GpioConfig& g, LiveProbe& probe, std::vector<CheckResult>& out) {
  struct Line {
    const char* key;
    int offset;
  };
  const Line lines[] = {{"frame_sync_line", g.frame_sync_line}, {"pose_valid_line", g.pose_valid_line},
                        {"heartbeat_line", g.heartbeat_line}};
  bool any = false;
  for (const auto& l : lines) {
    if (l.offset < 0) continue;
    any = true;
    const std::string name = std::string("gpio.") + l.key;
    const GpioLineUse u = probe.gpio_line(g.chip, l.offset);
    const std::string where = "line " + std::to_string(l.offset) + " of '" + g.chip + "'";
    if (!u.chip_found) {
      out.push_back(fail(name, "GPIO chip '" + g.chip + "' cannot be opened (" + u.chip_problem + ")",
                         "check gpio.chip against gpiodetect, and that the sempose group may open /dev/gpiochip* (package udev rule)"));
    } else if (!u.line_exists) {
      out.push_back(fail(name, where + " does not exist", "check the line offset with gpioinfo " + g.chip));
    } else if (u.used) {
      out.push_back(fail(name, where + " is in use by '" + (u.consumer.empty() ? "?" : u.consumer) + "'" +
                                   (u.consumer == g.consumer ? " (is sempose already running?)" : ""),
                         "free the line (stop its user, or unbind the kernel driver holding it) or choose another"));
    } else {
      out.push_back(pass(name, where + " free"));
    }
  }
  if (!any) out.push_back(pass("gpio", "no GPIO lines configured"));
}

void check_scan_source(const SystemTree& tree, const config::AppConfig& cfg, LiveProbe& probe, std::vector<CheckResult>& out) {
  if (cfg.source == "comedi") {
    // The card's device node must exist and be read/writable by this user (the package's
    // udev rule gives the sempose group /dev/comedi*); the card itself is probed at start.
    const std::string dev = config::scan_device_path(cfg);
    const std::string rel = !dev.empty() && dev[0] == '/' ? dev.substr(1) : dev;
    if (dev.empty() || !tree.exists(rel)) {
      out.push_back(fail("scan-device", "Comedi device '" + dev + "' missing",
                         "load the card's driver (e.g. modprobe ni_pcimio) and check comedi.device against /dev/comedi*"));
    } else if (!tree.writable(rel)) {
      out.push_back(fail("scan-device", "Comedi device '" + dev + "' not writable by this user",
                         "add the user to the sempose group (package udev rule) or fix the node's permissions"));
    } else if (const std::string why = probe.comedi_problem(tree.path(rel)); !why.empty()) {
      out.push_back(fail("scan-device", "comedi.device '" + dev + "' " + why,
                         "check comedi.device against /dev/comedi* (comedi_config; the card's driver loaded)"));
    } else {
      out.push_back(pass("scan-device", "Comedi device " + dev + " present, writable, answers COMEDI_DEVINFO"));
    }
  } else if (cfg.source == "sim") {
    out.push_back(pass("scan-device", "simulated SEM: no scan device needed"));
  } else if (cfg.source == "replay") {
    std::error_code ec;
    if (std::filesystem::is_directory(cfg.replay.frames_dir, ec)) out.push_back(pass("scan-device", "replay folder " + cfg.replay.frames_dir + " present"));
    else
      out.push_back(fail("scan-device", "replay folder '" + cfg.replay.frames_dir + "' missing",
                         "set replay.frames_dir to a recorded sequence (a folder of frame_N.pgm)"));
  } else {
    out.push_back(warn("scan-device", "source '" + cfg.source + "': no presence check implemented", "check the device by hand"));
  }
}

// The outputs as this user sees them (always the live file system, also under --root): the
// service user may not write a folder the engineer running check-rt can, and the reverse.
void check_outputs(const config::AppConfig& cfg, std::vector<CheckResult>& out) {
  // Without a config the built-in defaults' outputs (relative names) say nothing about a service.
  if (cfg.path.empty()) return;
  const auto problems = config::output_problems(cfg);
  for (const auto& p : problems) {
    out.push_back(fail(
        "outputs", p.key + ": " + p.what,
        "make the folder writable by the user that runs sempose (the packaged unit: user sempose, "
        "/var/log/sempose), or name another path"));
  }
  if (!problems.empty()) return;
  std::string what;
  auto add = [&what](const std::string& name, const std::string& path) {
    if (path.empty()) return;
    what += (what.empty() ? "" : ", ") + name + " " + path;
  };
  add("poses CSV", cfg.output.poses_csv);
  if (cfg.can.interface.empty()) add("candump log", cfg.can.log_file);
  add("histograms in", cfg.output.hist_dir);
  out.push_back(pass(
      "outputs", what.empty() ? "no file outputs configured" : what + ": writable by this user"));
}

}  // namespace

std::vector<CheckResult> run_checks(const SystemTree& tree, const config::AppConfig& cfg, LiveProbe& probe) {
  std::vector<CheckResult> out;
  const auto& p = cfg.pipeline;
  const bool spin = p.polling == "spin";
  const std::vector<int> rt = rt_cpus(p);
  const auto online_text = tree.read("sys/devices/system/cpu/online");
  const auto online_parsed = parse_cpu_list(online_text.value_or(""));
  const std::vector<int> online = online_parsed.value_or(std::vector<int>{});
  check_kernel(tree, out);
  // The online cores are what the core checks judge against: unread or unparseable, they are
  // not judged against nothing (found probing: "online: " for a list it could not parse).
  if (!online_text || !online_parsed || online.empty()) {
    out.push_back(fail("rt-cpus",
                       !online_text ? std::string("cannot read /sys/devices/system/cpu/online: the online cores are unknown")
                                    : "/sys/devices/system/cpu/online holds '" + online_text->substr(0, 64) +
                                          "', not a list of cores",
                       "run on a Linux system with /sys mounted (check-rt --root: a tree with sys/devices/system/cpu/online)"));
  } else {
    check_cpus(rt, online, out);
  }
  check_isolation(tree, rt, online, spin, out);
  check_throttling(tree, spin, out);
  check_governor(tree, rt, out);
  check_dma_latency(tree, p, out);
  check_irqs(tree, rt, online, out);
  check_limits(tree, p, out);
  check_can(tree, cfg.can, probe, out);
  check_gpio(cfg.gpio, probe, out);
  check_scan_source(tree, cfg, probe, out);
  check_outputs(cfg, out);
  return out;
}

const char* to_string(Level level) {
  switch (level) {
    case Level::kPass: return "PASS";
    case Level::kWarn: return "WARN";
    case Level::kFail: return "FAIL";
  }
  return "?";
}

std::string format_result(const CheckResult& r) {
  char name[24];
  std::snprintf(name, sizeof name, "%-16s", r.name.c_str());
  std::string line = std::string(to_string(r.level)) + "  " + name + " " + r.detail;
  if (!r.fix.empty()) line += "  -- fix: " + r.fix;
  return line;
}

int exit_code(const std::vector<CheckResult>& results) {
  int code = 0;
  for (const auto& r : results) {
    if (r.level == Level::kFail) return 3;
    if (r.level == Level::kWarn) code = 1;
  }
  return code;
}

}  // namespace sempose::check_rt
