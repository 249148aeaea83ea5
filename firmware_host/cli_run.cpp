// Placeholder until the issue that builds `sempose run` lands.
#include <cstdio>

#include "cli.hpp"

int sempose::cli::run(int, char**) {
  std::fprintf(stderr, "sempose run: not built yet\n");
  return 3;
}
