// check-rt on fake /proc and /sys trees: each check passes on a well-tuned tree, and each
// mis-setting turns exactly its own line to warn or fail, with a fix that names the remedy.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include "sempose/check_rt/checks.hpp"

namespace fs = std::filesystem;
using namespace sempose;
using check_rt::Level;

namespace {

class FakeProbe : public check_rt::LiveProbe {
 public:
  std::optional<check_rt::CanLinkDetails> can;
  std::map<int, check_rt::GpioLineUse> lines;
  std::optional<check_rt::CanLinkDetails> can_link(const std::string&) override { return can; }
  check_rt::GpioLineUse gpio_line(const std::string&, int line) override {
    auto it = lines.find(line);
    return it == lines.end() ? check_rt::GpioLineUse{} : it->second;
  }
  std::string comedi;  // what the node is not (empty: a Comedi device)
  std::string comedi_problem(const std::string&) override { return comedi; }
};

// A tuned 4-core PREEMPT_RT box: cores 2,3 isolated, throttling off, performance governor,
// IRQs on 0-1, CAP_SYS_NICE + CAP_IPC_LOCK held.
class FakeTree : public ::testing::Test {
 protected:
  fs::path root;
  config::AppConfig cfg;
  FakeProbe probe;

  void SetUp() override {
    root = fs::temp_directory_path() / ("sempose_check_rt_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root);
    put("sys/kernel/realtime", "1\n");
    put("proc/sys/kernel/osrelease", "6.1.0-31-rt-amd64\n");
    put("proc/sys/kernel/version", "#1 SMP PREEMPT_RT Debian 6.1.128-1\n");
    put("proc/cmdline", "BOOT_IMAGE=/vmlinuz root=/dev/sda1 isolcpus=2,3 nohz_full=2-3 rcu_nocbs=2-3 irqaffinity=0-1\n");
    put("sys/devices/system/cpu/online", "0-3\n");
    put("sys/devices/system/cpu/isolated", "2-3\n");
    put("sys/devices/system/cpu/nohz_full", "2-3\n");
    put("proc/sys/kernel/sched_rt_runtime_us", "-1\n");
    put("proc/sys/kernel/sched_rt_period_us", "1000000\n");
    for (int c = 0; c < 4; ++c) put("sys/devices/system/cpu/cpu" + std::to_string(c) + "/cpufreq/scaling_governor", "performance\n");
    put("dev/cpu_dma_latency", "");
    for (int irq : {1, 9, 24, 25}) put("proc/irq/" + std::to_string(irq) + "/smp_affinity_list", "0-1\n");
    put("proc/irq/default_smp_affinity", "3\n");
    put("proc/self/status", "Name:\tsempose\nCapInh:\t0000000000000000\nCapEff:\t0000000000804000\n");
    put("proc/self/limits",
        "Limit                     Soft Limit           Hard Limit           Units\n"
        "Max locked memory         8388608              8388608              bytes\n"
        "Max realtime priority     0                    0\n");
    cfg.pipeline.acquisition = {2, 60};
    cfg.pipeline.correlation = {3, 50};
    cfg.pipeline.output = {3, 40};
  }
  void TearDown() override { fs::remove_all(root); }

  void put(const std::string& rel, const std::string& text) {
    fs::create_directories((root / rel).parent_path());
    std::ofstream(root / rel) << text;
  }
  std::vector<check_rt::CheckResult> run() {
    check_rt::SystemTree tree(root.string());
    return check_rt::run_checks(tree, cfg, probe);
  }
  static const check_rt::CheckResult& find(const std::vector<check_rt::CheckResult>& r, const std::string& name) {
    for (const auto& x : r) {
      if (x.name == name) return x;
    }
    static check_rt::CheckResult none{"(missing)", Level::kFail, "no such check", ""};
    ADD_FAILURE() << "no check named " << name;
    return none;
  }
  // Everything but `name` still passes (a mis-setting affects its own line only).
  static void only(const std::vector<check_rt::CheckResult>& r, const std::string& name) {
    for (const auto& x : r) {
      if (x.name != name) {
        EXPECT_EQ(x.level, Level::kPass) << check_rt::format_result(x);
      }
    }
  }
};

TEST_F(FakeTree, TunedBoxPassesEveryCheck) {
  const auto r = run();
  for (const auto& x : r) {
    EXPECT_EQ(x.level, Level::kPass) << check_rt::format_result(x);
  }
  EXPECT_EQ(check_rt::exit_code(r), 0);
  EXPECT_GE(r.size(), 12u);
}

TEST_F(FakeTree, GenericKernelFailsWithTheRtKernelAsFix) {
  fs::remove(root / "sys/kernel/realtime");
  put("proc/sys/kernel/version", "#1 SMP PREEMPT_DYNAMIC Debian 6.1.128-1\n");
  const auto r = run();
  const auto& k = find(r, "kernel");
  EXPECT_EQ(k.level, Level::kFail);
  EXPECT_NE(k.fix.find("linux-image-rt-amd64"), std::string::npos);
  EXPECT_EQ(check_rt::exit_code(r), 3);
  only(r, "kernel");
}

TEST_F(FakeTree, RealtimeFlagAloneIsEnough) {
  put("proc/sys/kernel/version", "#1 SMP\n");  // some RT kernels do not say it in the version
  EXPECT_EQ(find(run(), "kernel").level, Level::kPass);
}

TEST_F(FakeTree, MissingIsolationWarnsWhenSleepingFailsWhenSpinning) {
  put("sys/devices/system/cpu/isolated", "\n");
  put("sys/devices/system/cpu/nohz_full", "(null)\n");
  put("proc/cmdline", "root=/dev/sda1 rcu_nocbs=3\n");
  auto r = run();
  for (const char* n : {"isolcpus", "nohz_full", "rcu_nocbs"}) {
    EXPECT_EQ(find(r, n).level, Level::kWarn) << n;
    EXPECT_NE(find(r, n).fix.find("isolcpus=2-3 nohz_full=2-3 rcu_nocbs=2-3"), std::string::npos) << find(r, n).fix;
  }
  EXPECT_NE(find(r, "rcu_nocbs").detail.find("core(s) 2 "), std::string::npos) << find(r, "rcu_nocbs").detail;
  EXPECT_EQ(check_rt::exit_code(r), 1);
  cfg.pipeline.polling = "spin";
  r = run();
  for (const char* n : {"isolcpus", "nohz_full", "rcu_nocbs"}) {
    EXPECT_EQ(find(r, n).level, Level::kFail) << n;
  }
}

// Found by the twelfth hostile-input round: nohz_full alone offloads RCU (the kernel adds its
// cores to the no-callback set), "all" is a list, quotes are dropped, and the last of two
// rcu_nocbs= is the kernel's (the first was read: a false PASS).
TEST_F(FakeTree, RcuNocbsIsReadAsTheKernelReadsIt) {
  put("proc/cmdline", "root=/dev/sda1 isolcpus=2,3 nohz_full=2-3\n");
  EXPECT_EQ(find(run(), "rcu_nocbs").level, Level::kPass) << find(run(), "rcu_nocbs").detail;
  put("sys/devices/system/cpu/nohz_full", "(null)\n");
  for (const char* line : {"root=/dev/sda1 rcu_nocbs=all\n", "root=/dev/sda1 \"rcu_nocbs=2-3\"\n",
                           "root=/dev/sda1 rcu_nocbs=\"2-3\"\n", "root=/dev/sda1 rcu_nocbs=0 rcu_nocbs=2-3\n",
                           "root=/dev/sda1 rcu_nocbs=2-N\n", "root=/dev/sda1 rcu_nocbs=0-3:2/2\n",
                           "root=/dev/sda1 rcu_nocbs=2-7:2/4\n"}) {
    put("proc/cmdline", line);
    EXPECT_EQ(find(run(), "rcu_nocbs").level, Level::kPass) << line << find(run(), "rcu_nocbs").detail;
  }
  put("proc/cmdline", "root=/dev/sda1 rcu_nocbs=2-3 rcu_nocbs=0\n");
  EXPECT_EQ(find(run(), "rcu_nocbs").level, Level::kWarn) << "the kernel keeps the last";
  put("proc/cmdline", "root=/dev/sda1 rcu_nocbs=0 -- rcu_nocbs=2-3\n");
  EXPECT_EQ(find(run(), "rcu_nocbs").level, Level::kWarn) << "after -- the words are init's";
  // The group form "lo-hi:used/group" is the kernel's (bitmap_parselist): 0-3:1/2 is CPUs 0 and
  // 2, 0-3:1/4 CPU 0 only. Read as every CPU it passed (hostile round 9).
  for (const char* line : {"root=/dev/sda1 rcu_nocbs=0-3:1/2\n", "root=/dev/sda1 rcu_nocbs=0-3:1/4\n"}) {
    put("proc/cmdline", line);
    EXPECT_EQ(find(run(), "rcu_nocbs").level, Level::kWarn) << line << find(run(), "rcu_nocbs").detail;
  }
}

TEST_F(FakeTree, RtThrottling) {
  put("proc/sys/kernel/sched_rt_runtime_us", "950000\n");
  auto r = run();
  EXPECT_EQ(find(r, "rt-throttling").level, Level::kWarn);
  EXPECT_NE(find(r, "rt-throttling").fix.find("sched_rt_runtime_us=-1"), std::string::npos);
  only(r, "rt-throttling");
  cfg.pipeline.polling = "spin";
  EXPECT_EQ(find(run(), "rt-throttling").level, Level::kFail);
  // No RT time at all is a FAIL however the stages wait (it was a WARN); blanks are not part of
  // the value ("on: RT threads get -1  of every").
  cfg.pipeline.polling = "sleep";
  put("proc/sys/kernel/sched_rt_runtime_us", "0\n");
  EXPECT_EQ(find(run(), "rt-throttling").level, Level::kFail) << find(run(), "rt-throttling").detail;
  put("proc/sys/kernel/sched_rt_runtime_us", "-1 \n");
  EXPECT_EQ(find(run(), "rt-throttling").level, Level::kPass) << find(run(), "rt-throttling").detail;
}

TEST_F(FakeTree, PowersaveGovernorOnAnRtCoreWarns) {
  put("sys/devices/system/cpu/cpu3/cpufreq/scaling_governor", "powersave\n");
  put("sys/devices/system/cpu/cpu0/cpufreq/scaling_governor", "powersave\n");  // housekeeping: fine
  const auto r = run();
  const auto& g = find(r, "cpufreq");
  EXPECT_EQ(g.level, Level::kWarn);
  EXPECT_NE(g.detail.find("core(s) 3"), std::string::npos) << g.detail;
  EXPECT_NE(g.fix.find("-c 3 -g performance"), std::string::npos) << g.fix;
  only(r, "cpufreq");
}

TEST_F(FakeTree, NoCpufreqIsAFixedClock) {
  fs::remove_all(root / "sys/devices/system/cpu/cpu2");
  fs::remove_all(root / "sys/devices/system/cpu/cpu3");
  EXPECT_EQ(find(run(), "cpufreq").level, Level::kPass);
}

TEST_F(FakeTree, DmaLatencyDeviceMissingOrReadOnly) {
  fs::remove(root / "dev/cpu_dma_latency");
  auto r = run();
  EXPECT_EQ(find(r, "cpu-dma-latency").level, Level::kFail);
  only(r, "cpu-dma-latency");
  cfg.pipeline.hold_dma_latency = false;
  EXPECT_EQ(find(run(), "cpu-dma-latency").level, Level::kPass);
  if (::geteuid() != 0) {  // root may write anything: the read-only case needs a normal user
    cfg.pipeline.hold_dma_latency = true;
    put("dev/cpu_dma_latency", "");
    ::chmod((root / "dev/cpu_dma_latency").c_str(), 0444);
    EXPECT_EQ(find(run(), "cpu-dma-latency").level, Level::kFail);
  }
}

TEST_F(FakeTree, IrqsAllowedOnRtCoresWarnAndNameThem) {
  put("proc/irq/25/smp_affinity_list", "0-3\n");
  put("proc/irq/30/smp_affinity_list", "3\n");
  const auto r = run();
  const auto& i = find(r, "irq-affinity");
  EXPECT_EQ(i.level, Level::kWarn);
  EXPECT_NE(i.detail.find("2 of 5 IRQs"), std::string::npos) << i.detail;
  EXPECT_NE(i.detail.find("(25,30)"), std::string::npos) << i.detail;
  EXPECT_NE(i.fix.find("irqaffinity=0-1"), std::string::npos) << i.fix;
  only(r, "irq-affinity");
}

// What cannot be parsed is not passed as "none may run on RT cores" (twelfth round).
TEST_F(FakeTree, IrqListsThatDoNotParseAreNotPassed) {
  for (int irq : {1, 9}) put("proc/irq/" + std::to_string(irq) + "/smp_affinity_list", "garbage\n");
  auto r = run();
  EXPECT_EQ(find(r, "irq-affinity").level, Level::kWarn);
  EXPECT_NE(find(r, "irq-affinity").detail.find("cannot parse /proc/irq/1/smp_affinity_list and 1 more"), std::string::npos)
      << find(r, "irq-affinity").detail;
  only(r, "irq-affinity");
  for (int irq : {1, 9}) put("proc/irq/" + std::to_string(irq) + "/smp_affinity_list", "0-1\n");
  put("proc/irq/default_smp_affinity", "zz\n");
  r = run();
  EXPECT_EQ(find(r, "irq-affinity").level, Level::kWarn);
  EXPECT_NE(find(r, "irq-affinity").detail.find("cannot parse /proc/irq/default_smp_affinity"), std::string::npos)
      << find(r, "irq-affinity").detail;
}

TEST_F(FakeTree, DefaultIrqAffinityOnRtCoresWarns) {
  put("proc/irq/default_smp_affinity", "f\n");
  const auto r = run();
  const auto& i = find(r, "irq-affinity");
  EXPECT_EQ(i.level, Level::kWarn);
  EXPECT_NE(i.detail.find("new IRQs default there"), std::string::npos) << i.detail;
}

TEST_F(FakeTree, NoCapabilitiesAndLowLimitsFail) {
  put("proc/self/status", "Name:\tsempose\nCapEff:\t0000000000000000\n");
  auto r = run();
  EXPECT_EQ(find(r, "memlock").level, Level::kFail);
  EXPECT_NE(find(r, "memlock").fix.find("LimitMEMLOCK=infinity"), std::string::npos);
  EXPECT_EQ(find(r, "rtprio").level, Level::kFail);
  EXPECT_NE(find(r, "rtprio").fix.find("LimitRTPRIO=60"), std::string::npos) << find(r, "rtprio").fix;
  // The limits alone are enough without the capabilities.
  put("proc/self/limits",
      "Max locked memory         unlimited            unlimited            bytes\n"
      "Max realtime priority     60                   60\n");
  r = run();
  EXPECT_EQ(find(r, "memlock").level, Level::kPass);
  EXPECT_EQ(find(r, "rtprio").level, Level::kPass);
  put("proc/self/limits", "Max realtime priority     59                   59\n");
  EXPECT_EQ(find(run(), "rtprio").level, Level::kFail);
  // Numbers of any size (hostile round 9): a priority limit of 2^32 overflowed and read as 0,
  // "below the configured 60"; a locked-memory limit of 1 TiB was a FAIL whatever its size. A
  // large number may or may not hold the whole process: said, not passed.
  put("proc/self/limits",
      "Max locked memory         1099511627776        1099511627776        bytes\n"
      "Max realtime priority     4294967296           4294967296\n");
  r = run();
  EXPECT_EQ(find(r, "memlock").level, Level::kWarn) << find(r, "memlock").detail;
  EXPECT_EQ(find(r, "rtprio").level, Level::kPass) << find(r, "rtprio").detail;
  // A CapEff that is not the kernel's 16 hex digits is not read as held ("-1" wrapped to every
  // capability; "4000zz" was read as 4000, CAP_IPC_LOCK).
  put("proc/self/limits", "Max locked memory         65536                65536                bytes\n");
  for (const char* cap : {"-1", "4000zz", "0x4000", "", "10000000000004000"}) {
    put("proc/self/status", std::string("Name:\tsempose\nCapEff:\t") + cap + "\n");
    r = run();
    EXPECT_EQ(find(r, "memlock").level, Level::kFail) << cap << ": " << find(r, "memlock").detail;
  }
}

// Files that are there but hold what the kernel never writes are not passed (hostile round 9):
// a governor that is a directory passed as "no frequency scaling", every IRQ list a directory
// or empty as "none may run on RT cores", a throttling runtime of "abc" was quoted as RT time.
TEST_F(FakeTree, UnreadOrMalformedFilesAreNotPassed) {
  fs::remove(root / "sys/devices/system/cpu/cpu3/cpufreq/scaling_governor");
  fs::create_directories(root / "sys/devices/system/cpu/cpu3/cpufreq/scaling_governor");
  auto r = run();
  EXPECT_EQ(find(r, "cpufreq").level, Level::kWarn) << find(r, "cpufreq").detail;
  EXPECT_NE(find(r, "cpufreq").detail.find("cannot read the scaling governor of RT core(s) 3"), std::string::npos)
      << find(r, "cpufreq").detail;
  // Each slow governor with its own cores (the last one read was named for all of them).
  put("sys/devices/system/cpu/cpu2/cpufreq/scaling_governor", "powersave\n");
  fs::remove_all(root / "sys/devices/system/cpu/cpu3/cpufreq/scaling_governor");
  put("sys/devices/system/cpu/cpu3/cpufreq/scaling_governor", "ondemand\n");
  r = run();
  EXPECT_NE(find(r, "cpufreq").detail.find("governor 'powersave' on RT core(s) 2, 'ondemand' on RT core(s) 3"), std::string::npos)
      << find(r, "cpufreq").detail;
  fs::remove(root / "sys/devices/system/cpu/cpu3/cpufreq/scaling_governor");
  fs::create_directories(root / "sys/devices/system/cpu/cpu3/cpufreq/scaling_governor");
  // An unread core is named beside a slow one too (only the slow one was).
  put("sys/devices/system/cpu/cpu2/cpufreq/scaling_governor", "powersave\n");
  r = run();
  EXPECT_EQ(find(r, "cpufreq").level, Level::kWarn) << find(r, "cpufreq").detail;
  EXPECT_NE(find(r, "cpufreq").detail.find("governor 'powersave' on RT core(s) 2"), std::string::npos) << find(r, "cpufreq").detail;
  EXPECT_NE(find(r, "cpufreq").detail.find("cannot read the scaling governor of RT core(s) 3"), std::string::npos)
      << find(r, "cpufreq").detail;
  for (const std::string& irq : {std::string("1"), std::string("9")}) put("proc/irq/" + irq + "/smp_affinity_list", "\n");
  r = run();
  EXPECT_EQ(find(r, "irq-affinity").level, Level::kWarn) << find(r, "irq-affinity").detail;
  for (const char* value : {"abc", "", "1e6", "+5", "-", "--1", "0x10", "99999999999999999999999"}) {
    put("proc/sys/kernel/sched_rt_runtime_us", std::string(value) + "\n");
    r = run();
    EXPECT_EQ(find(r, "rt-throttling").level, Level::kWarn) << value;
    EXPECT_NE(find(r, "rt-throttling").detail.find("not a number"), std::string::npos) << find(r, "rt-throttling").detail;
  }
  put("proc/sys/kernel/sched_rt_runtime_us", "00\n");
  EXPECT_EQ(find(run(), "rt-throttling").level, Level::kFail) << "00 is no RT time, as 0 is";
}

TEST_F(FakeTree, OfflineOrEveryCoreAsRtCore) {
  cfg.pipeline.correlation.cpu = 7;
  auto r = run();
  EXPECT_EQ(find(r, "rt-cpus").level, Level::kFail);
  EXPECT_NE(find(r, "rt-cpus").detail.find("7 not online"), std::string::npos);
  put("sys/devices/system/cpu/online", "0-1\n");
  cfg.pipeline.acquisition.cpu = 0;
  cfg.pipeline.correlation.cpu = 1;
  EXPECT_EQ(find(run(), "rt-cpus").level, Level::kWarn);
}

TEST_F(FakeTree, CanLink) {
  cfg.can.interface = "can0";
  cfg.can.bitrate = 1000000;
  auto r = run();
  EXPECT_EQ(find(r, "can").level, Level::kFail);  // no such interface
  EXPECT_NE(find(r, "can").detail.find("no network interface 'can0'"), std::string::npos);
  put("sys/class/net/can0/type", "1\n");  // Ethernet
  put("sys/class/net/can0/flags", "0x1003\n");
  EXPECT_NE(find(run(), "can").detail.find("not a CAN interface"), std::string::npos);
  put("sys/class/net/can0/type", "280\n");
  put("sys/class/net/can0/flags", "0x80\n");  // down
  r = run();
  EXPECT_EQ(find(r, "can").level, Level::kFail);
  EXPECT_NE(find(r, "can").fix.find("ip link set can0 type can bitrate 1000000"), std::string::npos);
  put("sys/class/net/can0/flags", "zz\n");  // not the kernel's: not taken as up
  EXPECT_EQ(find(run(), "can").level, Level::kFail);
  put("sys/class/net/can0/flags", "0xc1\n");  // up
  probe.can = check_rt::CanLinkDetails{"can", 1000000, "error-active"};
  r = run();
  EXPECT_EQ(find(r, "can").level, Level::kPass) << find(r, "can").detail;
  only(r, "(none)");
  probe.can->bitrate = 500000;
  EXPECT_EQ(find(run(), "can").level, Level::kWarn);
  probe.can->bitrate = 1000000;
  probe.can->state = "error-passive";
  EXPECT_EQ(find(run(), "can").level, Level::kWarn);
  probe.can->state = "bus-off";
  EXPECT_EQ(find(run(), "can").level, Level::kFail);
  probe.can = check_rt::CanLinkDetails{"vcan", 0, ""};
  EXPECT_EQ(find(run(), "can").level, Level::kPass);
}

TEST_F(FakeTree, GpioLines) {
  cfg.gpio.chip = "gpiochip0";
  cfg.gpio.frame_sync_line = 17;
  cfg.gpio.pose_valid_line = 22;
  auto r = run();
  EXPECT_EQ(find(r, "gpio.frame_sync_line").level, Level::kFail);  // chip not found
  check_rt::GpioLineUse free_line{true, "", true, false, ""};
  probe.lines[17] = free_line;
  probe.lines[22] = free_line;
  r = run();
  EXPECT_EQ(find(r, "gpio.frame_sync_line").level, Level::kPass);
  EXPECT_EQ(find(r, "gpio.pose_valid_line").level, Level::kPass);
  probe.lines[22].used = true;
  probe.lines[22].consumer = "sempose";
  r = run();
  EXPECT_EQ(find(r, "gpio.pose_valid_line").level, Level::kFail);
  EXPECT_NE(find(r, "gpio.pose_valid_line").detail.find("already running"), std::string::npos);
  probe.lines[17].line_exists = false;
  EXPECT_NE(find(run(), "gpio.frame_sync_line").detail.find("does not exist"), std::string::npos);
}

TEST_F(FakeTree, ReplaySourceNeedsItsFolder) {
  cfg.source = "replay";
  cfg.replay.frames_dir = (root / "recording").string();
  const auto missing = find(run(), "scan-device");
  EXPECT_EQ(missing.level, Level::kFail);
  EXPECT_NE(missing.fix.find("replay.frames_dir"), std::string::npos) << missing.fix;  // the key that exists
  fs::create_directories(root / "recording");
  EXPECT_EQ(find(run(), "scan-device").level, Level::kPass);
}

// Outputs this user cannot write are a FAIL line of their own among the RT checks (they were a
// config error that hid every check: check-rt as the service user before its log folder existed).
TEST_F(FakeTree, AnOutputThisUserCannotWriteFailsItsOwnLine) {
  cfg.path = (root / "sempose.yaml").string();  // the outputs are a config's (none: not checked)
  cfg.output.poses_csv = (root / "out" / "poses.csv").string();
  cfg.can.log_file = (root / "out" / "can.log").string();
  cfg.output.hist_dir = (root / "out" / "hist").string();
  fs::create_directories(root / "out");
  const auto fine = run();
  only(fine, "");
  EXPECT_NE(find(fine, "outputs").detail.find("poses CSV " + cfg.output.poses_csv), std::string::npos);
  put("out/plain", "a file, not a folder\n");
  cfg.output.poses_csv = (root / "out" / "plain" / "poses.csv").string();
  put("out/hist", "a file where the histogram folder should be\n");
  const auto r = run();
  only(r, "outputs");
  int failed = 0;
  for (const auto& x : r) {
    if (x.name != "outputs") continue;
    EXPECT_EQ(x.level, Level::kFail) << check_rt::format_result(x);
    EXPECT_NE(x.fix.find("writable by the user that runs sempose"), std::string::npos) << x.fix;
    ++failed;
  }
  EXPECT_EQ(failed, 2);  // the CSV and the histogram folder, each named; the candump log passes silently
  EXPECT_EQ(check_rt::exit_code(r), 3);
  // The built-in defaults (no --config) name relative outputs in check-rt's own folder, nothing
  // a service writes: not checked.
  cfg.path.clear();
  for (const auto& x : run()) EXPECT_NE(x.name, "outputs") << check_rt::format_result(x);
}

// source: comedi: the configured device node (under the tree's root) must exist; its fix
// names the driver to load and the config key; only that line changes.
TEST_F(FakeTree, ComediSourceNeedsItsDevice) {
  cfg.source = "comedi";
  cfg.comedi.device = "/dev/comedi0";
  auto r = run();
  EXPECT_EQ(find(r, "scan-device").level, Level::kFail);
  EXPECT_NE(find(r, "scan-device").fix.find("comedi.device"), std::string::npos);
  only(r, "scan-device");
  put("dev/comedi0", "");
  EXPECT_EQ(find(run(), "scan-device").level, Level::kPass);
  // A node that is no Comedi device (a regular file, /dev/null, a folder): FAIL, as `run` refuses it.
  probe.comedi = "is not a Comedi device (COMEDI_DEVINFO: Inappropriate ioctl for device)";
  r = run();
  EXPECT_EQ(find(r, "scan-device").level, Level::kFail);
  EXPECT_NE(find(r, "scan-device").detail.find("comedi.device '/dev/comedi0' is not a Comedi device"), std::string::npos);
}

// The live probe asks the node what `run` asks it: a regular file, /dev/null and a folder are no
// Comedi device (check-rt passed them as "present and writable"; found probing).
TEST(LinuxProbe, NodesThatAreNoComediDeviceAreNamed) {
  check_rt::LinuxProbe probe;
  const std::string file = ::testing::TempDir() + "not_comedi_" + std::to_string(::getpid());
  std::ofstream(file) << "x";
  for (const std::string& path : {file, std::string("/dev/null")}) {
    EXPECT_NE(probe.comedi_problem(path).find("is not a Comedi device"), std::string::npos) << path;
  }
  EXPECT_NE(probe.comedi_problem("/").find("cannot be opened"), std::string::npos);
  std::remove(file.c_str());
}

// A GPIO chip path that is a file or a folder is named as what it is, as `run` names it (it was
// "cannot be opened (No such file or directory)"; hostile round 11).
TEST(LinuxProbe, GpioChipPathsThatAreNoChipAreNamed) {
  check_rt::LinuxProbe probe;
  const std::string file = ::testing::TempDir() + "not_gpio_" + std::to_string(::getpid());
  std::ofstream(file) << "x";
  EXPECT_EQ(probe.gpio_line(file, 3).chip_problem, "it is not a character device, not a GPIO chip");
  EXPECT_EQ(probe.gpio_line(::testing::TempDir(), 3).chip_problem, "it is a folder, not a GPIO chip");
  EXPECT_FALSE(probe.gpio_line(file, 3).chip_found);
  std::remove(file.c_str());
}

TEST(CpuLists, ParseKernelFormats) {
  EXPECT_EQ(check_rt::parse_cpu_list("0-3,8,10-11\n"), (std::vector<int>{0, 1, 2, 3, 8, 10, 11}));
  EXPECT_EQ(check_rt::parse_cpu_list("(null)"), std::vector<int>{});
  EXPECT_EQ(check_rt::parse_cpu_list(""), std::vector<int>{});
  EXPECT_FALSE(check_rt::parse_cpu_list("3-1"));
  EXPECT_FALSE(check_rt::parse_cpu_list("a"));
  EXPECT_EQ(check_rt::parse_cpu_mask("00000000,00000005"), (std::vector<int>{0, 2}));
  EXPECT_EQ(check_rt::parse_cpu_mask("f0"), (std::vector<int>{4, 5, 6, 7}));
  EXPECT_FALSE(check_rt::parse_cpu_mask("xyz"));
  EXPECT_EQ(check_rt::format_cpu_list({0, 1, 2, 5, 7, 8}), "0-2,5,7-8");
}

// A list of many overlapping ranges (a fake or corrupt tree: 100,000 × "0-65535" in 800 KB
// made `check-rt --root` run over a minute at 10 GB) lists each CPU once without expanding
// every range: here 1000 ranges, which took 260 MB of ints before. CPU numbers stay 0..65535.
TEST(CpuLists, ManyOverlappingRangesAreListedOnce) {
  std::string text;
  for (int i = 0; i < 1000; ++i) text += "0-65535,";
  text += "7";
  rusage before{}, after{};
  getrusage(RUSAGE_SELF, &before);
  const auto cpus = check_rt::parse_cpu_list(text);
  getrusage(RUSAGE_SELF, &after);
  ASSERT_TRUE(cpus);
  EXPECT_EQ(cpus->size(), 65536u);
  EXPECT_EQ(cpus->back(), 65535);
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "KB more at the peak: the ranges were expanded one by one";
  EXPECT_FALSE(check_rt::parse_cpu_list("70000"));
  EXPECT_EQ(check_rt::parse_cpu_list("5,1-3,2-6"), (std::vector<int>{1, 2, 3, 4, 5, 6}));
}

TEST(FormatResult, OneLineWithTheFix) {
  const std::string l = check_rt::format_result({"kernel", Level::kFail, "kernel 6.1 is not PREEMPT_RT", "install it"});
  EXPECT_EQ(l.rfind("FAIL  kernel", 0), 0u) << l;
  EXPECT_NE(l.find("-- fix: install it"), std::string::npos);
  EXPECT_EQ(l.find('\n'), std::string::npos);
}

// A --root tree with a FIFO or /dev/zero where check-rt reads a file: it blocked in open() for
// good (the FIFO) or read without end (/dev/zero). Now only regular files are read, and only
// their first MiB: the check whose file it is reports it as unreadable, the rest run.
TEST_F(FakeTree, AFifoOrDeviceInTheTreeIsNotRead) {
  fs::remove(root / "proc/cmdline");
  ASSERT_EQ(::mkfifo((root / "proc/cmdline").c_str(), 0644), 0);
  fs::remove(root / "proc/sys/kernel/version");
  fs::create_symlink("/dev/zero", root / "proc/sys/kernel/version");
  check_rt::SystemTree tree(root.string());
  EXPECT_FALSE(tree.read("proc/cmdline").has_value());
  EXPECT_FALSE(tree.read("proc/sys/kernel/version").has_value());
  put("proc/irq/default_smp_affinity", std::string(3 << 20, '3'));
  const auto big = tree.read("proc/irq/default_smp_affinity");
  ASSERT_TRUE(big.has_value());
  EXPECT_EQ(big->size(), std::size_t{1} << 20);
  const auto r = run();
  EXPECT_FALSE(r.empty());
}

// Found probing: an empty --root tree passed irq-affinity and cpufreq on data it never read,
// and an online list it could not parse showed as "online: ". Unread is said, never a pass.
TEST_F(FakeTree, WhatCannotBeReadIsNotPassed) {
  put("sys/devices/system/cpu/online", "0-99999999999999999999\n");
  auto r = run();
  EXPECT_EQ(find(r, "rt-cpus").level, Level::kFail);
  EXPECT_NE(find(r, "rt-cpus").detail.find("not a list of cores"), std::string::npos) << find(r, "rt-cpus").detail;
  fs::remove_all(root / "sys");
  fs::remove_all(root / "proc/irq");
  r = run();
  EXPECT_EQ(find(r, "rt-cpus").level, Level::kFail);
  EXPECT_EQ(find(r, "cpufreq").level, Level::kWarn) << find(r, "cpufreq").detail;
  EXPECT_EQ(find(r, "irq-affinity").level, Level::kWarn) << find(r, "irq-affinity").detail;
}

}  // namespace
