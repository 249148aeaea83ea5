#include "sempose/rt/rt_thread.hpp"

#include <sched.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/thread_room.hpp"

namespace sempose::rt {

namespace {
constexpr const char* kGrantHint =
    "run as root, or grant CAP_SYS_NICE (setcap cap_sys_nice+ep sempose) or an rtprio limit "
    "(ulimit -r 99; 'rtprio 99' in /etc/security/limits.conf)";

std::string errno_text(int err) { return std::strerror(err); }

// The cores the process may use as it started, before `sempose run` pins its main thread to
// pipeline.non_rt_cpu: an unpinned stage gets these. A new thread inherits its creator's
// affinity, so with non_rt_cpu: 1 a stage configured `cpu: -1` ran on core 1 only, beside the
// main thread, while the run said "unpinned".
const cpu_set_t g_process_cpus = [] {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) {
    for (int c = 0; c < CPU_SETSIZE; ++c) CPU_SET(c, &set);
  }
  return set;
}();
}  // namespace

__attribute__((noinline)) void prefault_stack(std::size_t bytes) noexcept {
  // One fixed frame (no recursion the compiler could fold into a loop, no alloca).
  constexpr std::size_t kMax = 512u << 10;
  volatile unsigned char frame[kMax];
  const std::size_t n = bytes < kMax ? bytes : kMax;
  for (std::size_t i = 0; i < n; i += 4096) frame[kMax - 1 - i] = 0;
  (void)frame[kMax - 1];
}

RtThread::~RtThread() { join(); }

void* RtThread::trampoline(void* self) {
  auto* t = static_cast<RtThread*>(self);
  prefault_stack(t->config_.prefault_stack_bytes);
  if (t->config_.count_allocations) alloc::arm_this_thread();
  t->body_();
  alloc::disarm_this_thread();
  return nullptr;
}

Status RtThread::start(const RtThreadConfig& config, std::function<void()> body) {
  if (started_) return Status::failure("thread '" + config.name + "' is already running");
  config_ = config;
  body_ = std::move(body);
  warning_.clear();

  const int max_prio = sched_get_priority_max(SCHED_FIFO);
  if (config.priority < 0 || config.priority > max_prio) {
    return Status::failure("thread '" + config.name + "': priority " +
                           std::to_string(config.priority) + " is outside 0.." +
                           std::to_string(max_prio));
  }
  const long cpus = sysconf(_SC_NPROCESSORS_CONF);
  if (config.cpu >= cpus) {
    const std::string msg = "thread '" + config.name + "': cpu " + std::to_string(config.cpu) +
                            " does not exist (this machine has 0.." + std::to_string(cpus - 1) + ")";
    if (config.strict) return Status::failure(msg);
    warning_ += msg + "; not pinned. ";
  }

  auto try_create = [&](bool realtime, bool pin) -> int {
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setstacksize(&attr, config.stack_bytes);
    if (realtime) {
      sched_param param{};
      param.sched_priority = config.priority;
      pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
      pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
      pthread_attr_setschedparam(&attr, &param);
    } else {
      // A normal thread says so explicitly: inherited, a launcher's policy (`chrt -f 5`, a unit's
      // CPUSchedulingPolicy=) made a priority-0 stage SCHED_FIFO while its line said SCHED_OTHER.
      sched_param param{};
      pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
      pthread_attr_setschedpolicy(&attr, SCHED_OTHER);
      pthread_attr_setschedparam(&attr, &param);
    }
    if (pin) {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(config.cpu, &set);
      pthread_attr_setaffinity_np(&attr, sizeof set, &set);
    } else {
      pthread_attr_setaffinity_np(&attr, sizeof g_process_cpus, &g_process_cpus);
    }
    const int rc = pthread_create(&handle_, &attr, &RtThread::trampoline, this);
    pthread_attr_destroy(&attr);
    return rc;
  };

  bool realtime = config.priority > 0;
  bool pin = config.cpu >= 0 && config.cpu < cpus;
  // Pinned where the config says, also outside the cores the process was started on (taskset, a
  // unit's CPUAffinity=): said, since whoever started it meant to keep it there (it went unsaid).
  if (pin && !CPU_ISSET(config.cpu, &g_process_cpus)) {
    warning_ += "thread '" + config.name + "': pinned to cpu " + std::to_string(config.cpu) +
                " as configured, outside the cores the process was started on (taskset, a unit's CPUAffinity=). ";
  }
  int rc = try_create(realtime, pin);
  if (rc == EPERM && realtime) {
    const std::string msg = "thread '" + config.name + "': SCHED_FIFO priority " +
                            std::to_string(config.priority) + " not permitted (" + kGrantHint + ")";
    if (config.strict) return Status::failure(msg + "; refusing to start (--strict-rt)");
    warning_ += msg + "; running at normal priority. ";
    realtime = false;
    rc = try_create(realtime, pin);
  }
  if (rc == EINVAL && pin) {
    const std::string msg = "thread '" + config.name + "': cannot pin to cpu " +
                            std::to_string(config.cpu) + " (offline or outside this cpuset)";
    if (config.strict) return Status::failure(msg + "; refusing to start (--strict-rt)");
    warning_ += msg + "; not pinned. ";
    pin = false;
    rc = try_create(realtime, pin);
  }
  if (rc != 0) {
    return Status::failure("thread '" + config.name + "': pthread_create failed: " + errno_text(rc) +
                           (rc == EAGAIN ? std::string(": ") + kThreadLimitHint : std::string()));
  }
  started_ = true;
  pthread_setname_np(handle_, config.name.substr(0, 15).c_str());
  placement_ = (realtime ? "SCHED_FIFO " + std::to_string(config.priority) : std::string("SCHED_OTHER")) +
               (pin ? " on cpu " + std::to_string(config.cpu) : std::string(" unpinned"));
  return Status::success();
}

void RtThread::join() {
  if (started_) {
    pthread_join(handle_, nullptr);
    started_ = false;
  }
}

}  // namespace sempose::rt
