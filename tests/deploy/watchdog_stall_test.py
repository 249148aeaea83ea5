#!/usr/bin/env python3
"""The systemd watchdog path of `sempose run`, exercised for real.

The test plays the service manager: it binds its own AF_UNIX datagram socket, starts
sempose with NOTIFY_SOCKET and WATCHDOG_USEC pointing at it, and records every datagram.
A stage is stalled the way it happens on a real box: a SCHED_FIFO 90 busy thread pinned to
the acquisition stage's core (FIFO 60) starves it, so no frame is scanned while the other
stages and the main thread run on. Checked:
  1. READY=1 after setup, then WATCHDOG=1 every WatchdogSec/2 while everything progresses;
  2. during the stall: a STATUS naming the acquisition stage, no WATCHDOG=1 after it (the gap
     exceeds WatchdogSec, so systemd would restart the service), and CAN heartbeats that go
     on with their `stalled` bit set;
  3. after the stall: STATUS=running and the pings resume;
  4. SIGUSR1 writes the histograms without stopping; SIGTERM drains: STOPPING=1 and exit 0
     within service.stop_timeout_ms;
  5. SIGTERM while the stage is still starved: exit code 4 within the same bound, not a hang.
Needs root (the stalling thread is SCHED_FIFO); exits 77 (skip) without it.
"""
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

WATCHDOG_S = 1.0
STALL_TIMEOUT_MS = 1000
STOP_TIMEOUT_MS = 1500
HEARTBEAT_ID = 0x140

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what, flush=True)
    if not ok:
        failures.append(what)


class Manager:
    """The service manager's side of sd_notify: a datagram socket and what arrived when."""

    def __init__(self, path):
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(path)
        self.sock.settimeout(0.2)
        self.messages = []  # (monotonic time, text)
        self.lock = threading.Lock()
        self.running = True
        self.thread = threading.Thread(target=self._receive, daemon=True)
        self.thread.start()

    def _receive(self):
        while self.running:
            try:
                data = self.sock.recv(4096)
            except socket.timeout:
                continue
            with self.lock:
                self.messages.append((time.monotonic(), data.decode(errors="replace")))

    def wait_for(self, text, timeout, after=0.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                for t, m in self.messages:
                    if t >= after and text in m:
                        return t
            time.sleep(0.02)
        return None

    def pings(self, start, end):
        with self.lock:
            return [t for t, m in self.messages if m == "WATCHDOG=1" and start <= t <= end]


def start_hog(cpu, seconds):
    """A FIFO 90 busy loop pinned to `cpu` for `seconds`: starves every lower RT thread there.
    Returns (process, monotonic time at which it started hogging)."""
    code = (
        "import os, sys, time\n"
        f"os.sched_setaffinity(0, {{{cpu}}})\n"
        "os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(90))\n"
        "sys.stdout.write('%.6f\\n' % time.monotonic()); sys.stdout.flush()\n"
        f"end = time.monotonic() + {seconds}\n"
        "while time.monotonic() < end: pass\n"
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    return p, float(p.stdout.readline())


def start_sempose(binary, work, notify_path, name):
    cfg = os.path.join(work, f"{name}.yaml")
    cpu1 = 1 if os.cpu_count() > 1 else 0
    with open(cfg, "w") as f:
        f.write(
            f"""sim: {{clock: real}}
pipeline:
  acquisition: {{cpu: 0, priority: 60}}
  correlation: {{cpu: {cpu1}, priority: 50}}
  output: {{cpu: {cpu1}, priority: 40}}
  non_rt_cpu: {cpu1}            # the non-RT thread (signals, watchdog) off the core that gets stalled
  stats_period_ms: 200
output: {{hist_dir: {work}/{name}_hist, print_status: false}}
can: {{log_file: {work}/{name}_can.log, heartbeat_hz: 20}}
service: {{stall_timeout_ms: {STALL_TIMEOUT_MS}, stop_timeout_ms: {STOP_TIMEOUT_MS}}}
""")
    env = dict(os.environ, NOTIFY_SOCKET=notify_path, WATCHDOG_USEC=str(int(WATCHDOG_S * 1e6)))
    out = open(os.path.join(work, f"{name}.out"), "w")
    proc = subprocess.Popen([binary, "run", "--config", cfg], env=env, stdout=out, stderr=subprocess.STDOUT)
    return proc, os.path.join(work, f"{name}_can.log"), os.path.join(work, f"{name}.out")


def heartbeats(can_log):
    """(timestamp, stalled bit) of every HEARTBEAT frame in a candump log."""
    out = []
    with open(can_log) as f:
        for line in f:
            parts = line.split()
            if len(parts) < 3 or "#" not in parts[2]:
                continue
            ident, data = parts[2].split("#", 1)
            if int(ident, 16) == HEARTBEAT_ID and len(data) >= 2:
                out.append((float(parts[0].strip("()")), (int(data[0:2], 16) >> 7) & 1))  # HEARTBEAT.stalled, bit 7 (ipc/sempose.dbc)
    return out


def wait_exit(proc, timeout):
    t0 = time.monotonic()
    try:
        rc = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return None, time.monotonic() - t0
    return rc, time.monotonic() - t0


def main():
    binary = sys.argv[1]
    if os.geteuid() != 0:
        print("skip: needs root for the SCHED_FIFO thread that stalls a stage")
        return 77
    if len(os.sched_getaffinity(0)) < 2 or not {0, 1} <= os.sched_getaffinity(0):
        print("skip: needs cpus 0 and 1 (one to stall, one for the watchdog and this test)")
        return 77
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except PermissionError:
        print("skip: SCHED_FIFO not permitted here")
        return 77
    # This process plays systemd: keep it off the core whose stage gets stalled.
    if os.cpu_count() > 1:
        os.sched_setaffinity(0, {1})
    work = tempfile.mkdtemp(prefix="sempose_watchdog_")
    notify_path = os.path.join(work, "notify.sock")
    mgr = Manager(notify_path)
    hogs = []
    try:
        # ---- run A: healthy, stalled, recovered, SIGTERM
        proc, can_log, out = start_sempose(binary, work, notify_path, "a")
        ready = mgr.wait_for("READY=1", 120)
        check(ready is not None, "READY=1 after setup")
        if ready is None:
            print(open(out).read())
            return 1
        time.sleep(3.0)
        healthy = mgr.pings(ready, time.monotonic())
        gaps = [b - a for a, b in zip(healthy, healthy[1:])]
        check(len(healthy) >= 4 and max(gaps) < WATCHDOG_S,
              f"healthy: {len(healthy)} WATCHDOG=1 in 3 s, largest gap {max(gaps, default=0):.2f} s < WatchdogSec {WATCHDOG_S} s")

        hog, hog_start = start_hog(0, 4.0)
        hogs.append(hog)
        stalled_at = mgr.wait_for("STATUS=stalled: acquisition", 4.0, after=hog_start)
        # + 1.5 s: the correlation thread, on the non-RT thread's core, polls every 5 us for a
        # frame until it is 250 ms overdue (then every idle_sleep_us); before that back-off the
        # report came 1.0-1.6 s late (2.0-2.6 s, failing 2 runs in 3 on a busy day), now 1.25 s.
        check(stalled_at is not None and stalled_at - hog_start < STALL_TIMEOUT_MS / 1000 + 1.5,
              "stall reported naming acquisition after %.2f s (stall_timeout %.1f s)"
              % ((stalled_at or 0) - hog_start, STALL_TIMEOUT_MS / 1000))
        hogs[-1].wait()
        hog_end = time.monotonic()
        during = mgr.pings((stalled_at or hog_start) + 0.05, hog_end)
        check(len(during) == 0, f"no WATCHDOG=1 while stalled ({len(during)} received)")
        recovered = mgr.wait_for("STATUS=running", 3.0, after=hog_end - 0.1)
        check(recovered is not None, "STATUS=running once frames flow again")
        time.sleep(1.5)
        check(len(mgr.pings(hog_end, time.monotonic())) >= 2, "pings resume after the stall")
        around = mgr.pings(hog_start - 2, time.monotonic())
        longest = max((b - a for a, b in zip(around, around[1:])), default=0)
        check(longest > WATCHDOG_S, f"longest ping gap {longest:.2f} s > WatchdogSec {WATCHDOG_S} s: systemd would restart it")
        time.sleep(0.5)  # one more stats period: the candump log is flushed by then
        # SIGUSR1 (`systemctl kill -s USR1 sempose`): histograms written without stopping.
        hist = os.path.join(work, "a_hist", "latency_hist.txt")
        proc.send_signal(signal.SIGUSR1)
        t_usr1 = time.monotonic()
        while not os.path.exists(hist) and time.monotonic() - t_usr1 < 3:
            time.sleep(0.05)
        check(os.path.exists(hist) and proc.poll() is None, "SIGUSR1: histograms written, still running")

        t_term = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        rc, took = wait_exit(proc, STOP_TIMEOUT_MS / 1000 + 10)
        check(mgr.wait_for("STOPPING=1", 1.0, after=t_term) is not None, "STOPPING=1 on SIGTERM")
        check(rc == 0 and took < STOP_TIMEOUT_MS / 1000 + 1.0, f"SIGTERM: exit {rc} after {took:.2f} s (bound {STOP_TIMEOUT_MS} ms)")

        beats = heartbeats(can_log)
        in_stall = [s for t, s in beats if (stalled_at or hog_start) + 0.1 <= t <= hog_end - 0.1]
        before = [s for t, s in beats if t < hog_start]
        check(len(before) > 10 and not any(before), f"{len(before)} heartbeats before the stall, none flagged")
        check(len(in_stall) >= 10 and all(in_stall),
              f"{len(in_stall)} heartbeats during the stall, all with stalled=1 (the bus sees the fault)")
        print("     sempose printed:", *[l.strip() for l in open(out) if l.startswith(("watchdog", "systemd"))], sep="\n       ")

        # ---- run B: SIGTERM while a stage is stuck: bounded, exit code 4
        proc, _, out = start_sempose(binary, work, notify_path, "b")
        ready = mgr.wait_for("READY=1", 120, after=t_term + took)
        check(ready is not None, "run B: READY=1")
        hog, hog_start = start_hog(0, 6.0)
        hogs.append(hog)
        stalled_at = mgr.wait_for("STATUS=stalled", 4.0, after=hog_start)
        check(stalled_at is not None, "run B: stall reported")
        t_term = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        gave_up = None
        while gave_up is None and time.monotonic() - t_term < STOP_TIMEOUT_MS / 1000 + 5:
            if "did not drain" in open(out).read():
                gave_up = time.monotonic() - t_term
            time.sleep(0.02)
        check(gave_up is not None and gave_up < STOP_TIMEOUT_MS / 1000 + 1.0,
              f"SIGTERM with a starved stage: sempose gave up the drain after {gave_up or -1:.2f} s (bound {STOP_TIMEOUT_MS} ms)")
        # The starved thread itself can only die once it is scheduled again (a kernel fact:
        # an exiting thread must run to exit), i.e. when the higher-priority thread lets go.
        rc, took = wait_exit(proc, 15)
        hog.wait()
        hog_end = time.monotonic()
        check(rc == 6 and t_term + took < hog_end + 1.0,
              f"exit code {rc}; process gone {t_term + took - hog_end:+.2f} s after the starving thread ended")
    finally:
        for h in hogs:
            if h.poll() is None:
                h.kill()
                h.wait()
        mgr.running = False
    if failures:
        print(f"watchdog_stall: {len(failures)} failed; outputs in {work}")
        return 1
    subprocess.run(["rm", "-rf", work])
    print("watchdog_stall: all passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
