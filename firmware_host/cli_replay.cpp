// Placeholder until the issue that builds `sempose replay` lands.
#include <cstdio>

#include "cli.hpp"

int sempose::cli::replay(int, char**) {
  std::fprintf(stderr, "sempose replay: not built yet\n");
  return 3;
}
