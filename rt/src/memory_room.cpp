#include "sempose/rt/memory_room.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <fstream>
#include <string>

namespace sempose::rt {

MemoryRoom memory_room() {
  MemoryRoom room;
  std::ifstream meminfo("/proc/meminfo");
  for (std::string key; meminfo >> key;) {
    std::uint64_t kb = 0;
    meminfo >> kb;
    if (key == "MemAvailable:") {
      room.available = kb * 1024;
      break;
    }
    meminfo.ignore(256, '\n');
  }
  rlimit as{};
  if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    std::uint64_t mapped_pages = 0;
    std::ifstream statm("/proc/self/statm");
    statm >> mapped_pages;
    const std::uint64_t mapped = mapped_pages * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
    room.address_limited = true;
    room.address_limit = as.rlim_cur;
    room.address_left = as.rlim_cur > mapped ? as.rlim_cur - mapped : 0;
  }
  return room;
}

}  // namespace sempose::rt
