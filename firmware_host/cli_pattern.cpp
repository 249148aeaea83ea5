// Placeholder until the issue that builds `sempose pattern` lands.
#include <cstdio>

#include "cli.hpp"

int sempose::cli::pattern(int, char**) {
  std::fprintf(stderr, "sempose pattern: not built yet\n");
  return 3;
}
