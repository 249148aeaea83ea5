#include "sempose/session/made_folders.hpp"

#include <algorithm>

namespace sempose::session {

bool MadeFolders::make(const std::filesystem::path& dir, std::error_code& ec) {
  namespace fs = std::filesystem;
  ec.clear();
  if (dir.empty()) return true;
  std::vector<fs::path> missing;  // innermost first
  std::error_code probe;
  for (fs::path p = dir; !p.empty() && !fs::exists(p, probe); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (!fs::create_directory(*it, probe)) break;  // a `..` or a race: create_directories below does the rest
    made_.push_back(*it);
  }
  fs::create_directories(dir, ec);
  if (ec) return false;
  if (!fs::is_directory(dir, ec)) {
    if (!ec) ec = std::make_error_code(std::errc::not_a_directory);
    return false;
  }
  return true;
}

void MadeFolders::remove_empty() noexcept {
  std::error_code ec;
  for (auto it = made_.rbegin(); it != made_.rend(); ++it) std::filesystem::remove(*it, ec);  // only when empty
  made_.clear();
}

bool MadeFolders::made(const std::filesystem::path& dir) const {
  return std::find(made_.begin(), made_.end(), dir) != made_.end();
}

}  // namespace sempose::session
