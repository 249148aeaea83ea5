// Placeholder until the issue that builds `sempose sim` lands.
#include <cstdio>

#include "cli.hpp"

int sempose::cli::sim(int, char**) {
  std::fprintf(stderr, "sempose sim: not built yet\n");
  return 3;
}
