// Whether the process may create the threads a run needs, tried before any output is touched.
// Found probing: under a thread limit (`prlimit --nproc=1`, a systemd unit's TasksMax=) the
// stages' pthread_create failed only after the poses CSV and the candump log had been emptied,
// so the previous run's outputs were gone and nothing ran. Setup only (creates and joins).
#pragma once

#include <cstddef>
#include <string>

#include "sempose/rt/result.hpp"

namespace sempose::rt {

// What to change when a thread cannot be created for want of room (EAGAIN).
inline constexpr const char* kThreadLimitHint =
    "the process's thread limit (ulimit -u, RLIMIT_NPROC; a systemd unit's TasksMax= or LimitNPROC=) "
    "or the system's (/proc/sys/kernel/threads-max) is reached, or an address-space limit (ulimit -v, "
    "RLIMIT_AS) leaves no room for the threads' stacks";

// Creates `count` threads with stacks of `stack_bytes` (the stages': RtThreadConfig) that all
// exist at once, then ends and joins them. Fails naming `what`, the count and the cause (with
// kThreadLimitHint when it is a limit).
Status try_thread_room(int count, std::size_t stack_bytes, const std::string& what);

}  // namespace sempose::rt
