// The folders an output path needs, made, with a record of which ones this call made: a command
// that is refused or stopped after making them takes them away again, so it leaves nothing
// behind (a refused `run` left `new1/sub` and `hist/deep`, a stopped `sim --out a/b/c` left `a/b`;
// hostile round 8).
#pragma once

#include <filesystem>
#include <vector>

namespace sempose::session {

class MadeFolders {
 public:
  // Makes `dir` and every missing folder above it (as create_directories), remembering the ones
  // that did not exist. False, with ec set, when the folder is not there afterwards.
  bool make(const std::filesystem::path& dir, std::error_code& ec);
  // Removes the folders make() made, deepest first, each only when empty (a file someone put
  // there keeps it and the folders above it).
  void remove_empty() noexcept;
  bool made(const std::filesystem::path& dir) const;

 private:
  std::vector<std::filesystem::path> made_;  // outermost first
};

}  // namespace sempose::session
