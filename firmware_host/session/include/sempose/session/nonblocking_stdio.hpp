// Standard output and error that never block the process that writes them (`sempose run`).
// A pipe nobody reads (`sempose run … | sleep 1000`, a stuck log collector, a terminal held with
// Ctrl-S) used to stall run's non-RT main loop in fflush(stdout): no CSV flushing, no watchdog
// feeding, no SIGTERM seen. After make_stdio_nonblocking() the global stdout and stderr are
// line-buffered streams whose writes wait at most until the patience deadline (none while
// running) and otherwise drop the line, counting it. Whole lines of up to PIPE_BUF bytes go
// to a pipe whole or not at all. Only status text goes this way: the CSV and the CAN log have
// their own files and counters.
// Non-RT only (the main thread); the RT stages never print.
#pragma once

#include <cstdint>

namespace sempose::session {

// Replaces stdout and stderr by non-blocking line streams on fds 1 and 2 (a FIFO or terminal
// gets a private O_NONBLOCK description of its own, so the shell's is not changed; a socket is
// written with MSG_DONTWAIT). Returns false, leaving them as they were, when it cannot.
bool make_stdio_nonblocking();
// From now on a write may wait for room until `ms` milliseconds from now (0: not at all): the
// summary at the end of a run gets a bounded chance to reach a slow reader.
void set_stdio_patience_ms(int ms);
// Lines (a cut line counts as one) that could not be written to stdout / stderr.
std::uint64_t stdout_lines_lost();
std::uint64_t stderr_lines_lost();

}  // namespace sempose::session
