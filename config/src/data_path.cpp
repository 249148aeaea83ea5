#include "sempose/config/data_path.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

#ifndef SEMPOSE_INSTALL_DATA_DIR
#define SEMPOSE_INSTALL_DATA_DIR "/usr/share/sempose"
#endif
#ifndef SEMPOSE_SOURCE_CONFIG_DIR
#define SEMPOSE_SOURCE_CONFIG_DIR ""
#endif
#ifndef SEMPOSE_BUILD_DIR
#define SEMPOSE_BUILD_DIR ""
#endif

namespace sempose::config {
namespace {

// What is wrong with `path` as a data file to read, or "" if nothing.
std::string file_problem(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    // Absent is "not found"; a link loop or a name too long is said as what it is (a loop was
    // reported as not found; hostile round 8).
    if (errno == ENOENT || errno == ENOTDIR) return "not found";
    return std::string("is not accessible (") + std::strerror(errno) + ")";
  }
  if (S_ISDIR(st.st_mode)) return "is a directory, not a file";
  if (!S_ISREG(st.st_mode)) return "is not a regular file (a FIFO, socket or device would block or never end)";
  if (::access(path.c_str(), R_OK) != 0) return "is not readable";
  return "";
}

// Whether this process's executable lies in the build tree it was compiled in. Such a binary
// belongs to that source tree: its data come from there even when a sempose package is installed
// (two checkouts' CIs on one machine: one's package test installing and removing
// /usr/share/sempose while the other's tests read their textures from it).
bool running_from_build_tree() {
  if (*SEMPOSE_BUILD_DIR == '\0') return false;
  std::error_code ec;
  // Both as the kernel names them: /proc/self/exe is canonical, the build folder may be reached by a link.
  const std::string build_dir = std::filesystem::weakly_canonical(SEMPOSE_BUILD_DIR, ec).string();
  if (ec) return false;
  const std::string exe = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  return !ec && exe.size() > build_dir.size() && exe.compare(0, build_dir.size(), build_dir) == 0 &&
         exe[build_dir.size()] == '/';
}

}  // namespace

std::vector<std::string> data_search_dirs(const std::string& config_path) {
  std::vector<std::string> dirs;
  if (!config_path.empty()) {
    const auto slash = config_path.rfind('/');
    dirs.push_back(slash == std::string::npos ? "." : config_path.substr(0, slash == 0 ? 1 : slash));
  }
  // An installed binary reads the installed data; one run from its build tree its own source
  // tree's first; the source tree stays the last resort of a binary copied out of the build tree.
  const bool build_tree = running_from_build_tree();
  for (const char* d : {build_tree ? SEMPOSE_SOURCE_CONFIG_DIR : SEMPOSE_INSTALL_DATA_DIR,
                        build_tree ? SEMPOSE_INSTALL_DATA_DIR : SEMPOSE_SOURCE_CONFIG_DIR}) {
    if (*d != '\0') dirs.emplace_back(d);
  }
  return dirs;
}

bool find_data_file(const std::string& file, const std::string& config_path, std::string& resolved,
                    std::string& problem) {
  if (file.empty()) {
    problem = "empty path";
    return false;
  }
  if (file[0] == '/') {
    problem = file_problem(file);
    resolved = file;
    return problem.empty();
  }
  std::string tried;
  std::string first_problem;
  for (const auto& dir : data_search_dirs(config_path)) {
    const std::string candidate = (dir == "/" ? "" : dir) + "/" + file;
    const std::string p = file_problem(candidate);
    if (p.empty()) {
      // Absolute, so that nothing later resolves it a second time against another folder.
      resolved = std::filesystem::absolute(candidate).lexically_normal().string();
      problem.clear();
      return true;
    }
    // A candidate that exists but is unusable is named; one that is simply absent only listed.
    if (p != "not found" && first_problem.empty()) first_problem = candidate + " " + p;
    tried += (tried.empty() ? "" : ", ") + candidate;
  }
  problem = first_problem.empty() ? "not found (tried: " + tried + ")" : first_problem + " (tried: " + tried + ")";
  return false;
}

}  // namespace sempose::config
