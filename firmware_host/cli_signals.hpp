// The signals that end a `sempose` command, and their names. Header-only: run, replay, sim and
// pattern share the list.
//
// A signal whose default action ends the process and that is a request from outside (a user,
// systemd, a timer, a supervisor) must end a command as SIGTERM does: `run` drains and writes
// its summary (exit 0); replay/sim/pattern remove the output they had begun, so that no
// half-written CSV, PGM or recording that looks whole is left behind. Found probing: SIGALRM,
// SIGUSR2 and SIGQUIT killed `sempose run` with their default action (no summary, CAN not
// stopped, the candump log unflushed).
//
// Not in the list, on purpose: the signals that say the process itself is broken (SIGSEGV,
// SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS — seccomp) and SIGABRT (abort(), and systemd's
// WatchdogSignal: its core dump is the point); SIGKILL and SIGSTOP cannot be caught; SIGXFSZ is
// ignored (main.cpp: a write error instead); SIGPIPE is ignored by `run`.
#pragma once

#include <signal.h>

#include <cstdio>
#include <cstdlib>

namespace sempose::cli {

// The fixed-number signals of the list (the real-time ones, SIGRTMIN..SIGRTMAX, are added by
// termination_signals(): SIGRTMIN is a run-time value under glibc).
inline constexpr int kTerminationSignals[] = {
    SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGALRM, SIGUSR1, SIGUSR2, SIGVTALRM, SIGPROF, SIGIO /* = SIGPOLL */,
#ifdef SIGPWR
    SIGPWR,
#endif
#ifdef SIGSTKFLT
    SIGSTKFLT,
#endif
    SIGXCPU /* CPU-time limit, and RLIMIT_RTTIME for an RT thread that never blocks: SIGKILL comes next */,
};

inline sigset_t termination_signals() {
  sigset_t set;
  sigemptyset(&set);
  for (int sig : kTerminationSignals) sigaddset(&set, sig);
  for (int sig = SIGRTMIN; sig <= SIGRTMAX; ++sig) sigaddset(&set, sig);
  return set;
}

// "SIGTERM", "SIGRTMIN+3", "SIGRTMAX"; the buffer holds the text for the real-time ones.
inline const char* signal_name(int sig, char (&buf)[24]) {
  switch (sig) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    case SIGHUP: return "SIGHUP";
    case SIGQUIT: return "SIGQUIT";
    case SIGALRM: return "SIGALRM";
    case SIGUSR1: return "SIGUSR1";
    case SIGUSR2: return "SIGUSR2";
    case SIGVTALRM: return "SIGVTALRM";
    case SIGPROF: return "SIGPROF";
    case SIGIO: return "SIGIO";
#ifdef SIGPWR
    case SIGPWR: return "SIGPWR";
#endif
#ifdef SIGSTKFLT
    case SIGSTKFLT: return "SIGSTKFLT";
#endif
    case SIGXCPU: return "SIGXCPU";
    default: break;
  }
  if (sig == SIGRTMIN) return "SIGRTMIN";
  if (sig == SIGRTMAX) return "SIGRTMAX";
  if (sig > SIGRTMIN && sig < SIGRTMAX) {
    std::snprintf(buf, sizeof buf, "SIGRTMIN+%d", sig - SIGRTMIN);
  } else {
    std::snprintf(buf, sizeof buf, "signal %d", sig);
  }
  return buf;
}

// For replay, sim and pattern (no RT threads): a handler that only records the signal. The
// command polls stop_requested() between frames, removes its incomplete output and then ends
// by the same signal (end_by_signal), so a shell or make sees what it asked for.
inline volatile sig_atomic_t g_stop_signal = 0;

inline void record_stop_signal(int sig) {
  if (g_stop_signal == 0) g_stop_signal = sig;
}

// A signal the parent set to be ignored (nohup's SIGHUP, a script's background job's SIGINT
// and SIGQUIT) stays ignored, as the convention for programs that catch signals is.
inline void catch_termination_signals() {
  struct sigaction sa {};
  sa.sa_handler = record_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  const sigset_t set = termination_signals();
  for (int sig = 1; sig < NSIG; ++sig) {
    struct sigaction old {};
    if (sigismember(&set, sig) != 1 || sigaction(sig, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) continue;
    sigaction(sig, &sa, nullptr);
  }
}

inline int stop_requested() { return g_stop_signal; }

// Ends the process by `sig` with its default action, as if the handler had not been there.
[[noreturn]] inline void end_by_signal(int sig) {
  std::fflush(stdout);
  std::fflush(stderr);
  ::signal(sig, SIG_DFL);
  sigset_t one;
  sigemptyset(&one);
  sigaddset(&one, sig);
  pthread_sigmask(SIG_UNBLOCK, &one, nullptr);
  ::raise(sig);
  std::_Exit(128 + sig);  // a default action that does not end the process (none in the list)
}

}  // namespace sempose::cli
