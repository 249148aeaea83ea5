#include "sempose/rt/memory_lock.hpp"

#include <fcntl.h>
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <string>

namespace sempose::rt {

Status lock_process_memory(bool strict) {
  // Keep every allocation in the heap (no mmap'd chunks to unmap) and never trim it.
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, -1);
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    const std::string msg = std::string("mlockall failed: ") + std::strerror(errno) +
                            " (needs root, CAP_IPC_LOCK or 'ulimit -l unlimited'; memlock in "
                            "/etc/security/limits.conf)";
    if (strict) return Status::failure(msg + "; refusing to start (--strict-rt)");
    return {true, msg + "; pages may fault in the loop"};
  }
  return Status::success();
}

CpuDmaLatencyHold::~CpuDmaLatencyHold() {
  if (fd_ >= 0) close(fd_);  // closing the fd releases the PM QoS request
}

Status CpuDmaLatencyHold::acquire(bool strict, const char* path) {
  if (fd_ >= 0) return Status::success();
  const int fd = open(path, O_RDWR | O_CLOEXEC);
  const std::int32_t zero = 0;
  if (fd < 0 || write(fd, &zero, sizeof zero) != static_cast<ssize_t>(sizeof zero)) {
    const std::string msg = std::string("cannot hold ") + path + " at 0 us: " +
                            std::strerror(errno) + " (needs root); CPUs may enter deep C-states";
    if (fd >= 0) close(fd);
    if (strict) return Status::failure(msg + "; refusing to start (--strict-rt)");
    return {true, msg};
  }
  fd_ = fd;
  return Status::success();
}

void prefault(void* p, std::size_t bytes) noexcept {
  const long page = sysconf(_SC_PAGESIZE);
  auto* bytes_ptr = static_cast<volatile unsigned char*>(p);
  for (std::size_t i = 0; i < bytes; i += static_cast<std::size_t>(page)) {
    bytes_ptr[i] = bytes_ptr[i];
  }
}

}  // namespace sempose::rt
