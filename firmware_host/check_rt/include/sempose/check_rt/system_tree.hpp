// Read-only view of /proc, /sys and /dev under a root folder: "/" on the live system, a
// fake tree in tests (e.g. root/sys/kernel/realtime holding "1").
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace sempose::check_rt {

class SystemTree {
 public:
  explicit SystemTree(std::string root = "/");
  // Full path of a file given relative to the root ("proc/cmdline").
  std::string path(const std::string& rel) const;
  // Whole file, or nullopt when it cannot be read. Trailing newlines removed.
  std::optional<std::string> read(const std::string& rel) const;
  bool exists(const std::string& rel) const;
  bool writable(const std::string& rel) const;  // access(W_OK) for the caller's identity
  std::vector<std::string> list(const std::string& rel_dir) const;  // entry names, sorted
  bool live() const noexcept { return root_ == "/"; }

 private:
  std::string root_;
};

// CPU lists as the kernel writes and reads them ("0-3,8,10-11", the group form "0-7:2/4");
// nullopt on syntax errors.
std::optional<std::vector<int>> parse_cpu_list(const std::string& text);
// Hex CPU masks ("ff" or "00000000,00000003" as in /proc/irq/*/smp_affinity).
std::optional<std::vector<int>> parse_cpu_mask(const std::string& text);
std::string format_cpu_list(const std::vector<int>& cpus);

}  // namespace sempose::check_rt
