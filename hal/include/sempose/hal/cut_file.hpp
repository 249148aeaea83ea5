#pragma once
// After a failed write: what the write left at `path` is removed only when it is a regular file
// (a cut PGM, PNG or plot file looks whole until something reads it). A device, a FIFO or a
// socket named as the output is never removed: `sempose pattern --out /dev/full` run as root
// unlinked the device node itself (found probing). Through a symlink the file it leads to is the
// one that was cut, and the one removed.
#include <sys/stat.h>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace sempose::hal {

// True when a regular file was there and is gone.
inline bool remove_cut_file(const std::string& path) noexcept {
  char* real = ::realpath(path.c_str(), nullptr);
  if (real == nullptr) return false;
  struct stat st {};
  const bool removed = ::stat(real, &st) == 0 && S_ISREG(st.st_mode) && std::remove(real) == 0;
  std::free(real);
  return removed;
}

// The words a write error ends with: what happened to the cut output.
inline const char* cut_file_outcome(bool removed) noexcept {
  return removed ? "removed the cut file" : "nothing removed (not a regular file)";
}

}  // namespace sempose::hal
