// The `sempose` subcommands. Each returns the process exit code; argv[0] is the subcommand.
#pragma once

namespace sempose::cli {

int run(int argc, char** argv);      // the controller: pipeline on a scan source (cli_run.cpp)
int sim(int argc, char** argv);      // record a simulated sequence (cli_sim.cpp)
int pattern(int argc, char** argv);  // average frames into a pattern PGM (cli_pattern.cpp)
int replay(int argc, char** argv);   // track through a recorded sequence (cli_replay.cpp)

}  // namespace sempose::cli
