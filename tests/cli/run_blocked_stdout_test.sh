#!/usr/bin/env bash
# `sempose run` with its standard output a pipe that is full and that nobody reads (`sempose
# run … | sleep 1000`, a stuck log collector). The non-RT main loop must go on flushing the
# CSV and must see SIGTERM: before, it blocked in fflush(stdout) before its first loop pass,
# so the CSV stayed empty and SIGTERM was never taken (the process hung until killed).
# The pipe is shrunk to one page and filled before sempose starts, so no timing decides what
# blocks; the bounds below (120 s: a Debug+ASan sempose starts slowly) only catch a hang.
set -euo pipefail
bin=${1:?usage: run_blocked_stdout_test.sh SEMPOSE}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/small_run_config.sh"
small_run_config "$work/poses.csv" "$work/can.log" >"$work/run.yaml"
python3 - "$bin" "$work" <<'PY'
import fcntl, os, re, signal, subprocess, sys, time
bin, work = sys.argv[1], sys.argv[2]
fails = 0
def ok(m): print("ok  ", m)
def bad(m):
    global fails
    print("FAIL", m); fails += 1
r, w = os.pipe()
fcntl.fcntl(w, fcntl.F_SETPIPE_SZ, 4096)
os.set_blocking(w, False)
try:
    while True:
        os.write(w, b"x" * 512)
except BlockingIOError:
    pass
os.set_blocking(w, True)  # the child gets a blocking, full pipe, as from a shell
err = open(os.path.join(work, "err.txt"), "w")
p = subprocess.Popen([bin, "run", "--config", os.path.join(work, "run.yaml")], stdout=w, stderr=err)
os.close(w)  # r stays open and unread: the pipe is full for the whole run
csv = os.path.join(work, "poses.csv")
def csv_lines():
    try:
        with open(csv) as f:
            return f.read().count("\n")
    except FileNotFoundError:
        return 0
t0 = time.monotonic()
while csv_lines() < 3 and p.poll() is None and time.monotonic() - t0 < 120:
    time.sleep(0.05)
n = csv_lines()
if n >= 3: ok(f"the CSV is flushed while stdout is blocked ({n} lines)")
else: bad(f"the CSV has {n} lines after {time.monotonic() - t0:.0f} s with stdout blocked (the main loop is stuck)")
p.send_signal(signal.SIGTERM)
try:
    code = p.wait(timeout=120)
    ok(f"SIGTERM ends the run (exit {code})")
    if code != 0: bad(f"exit code {code}, expected 0 (status lines are not outputs)")
except subprocess.TimeoutExpired:
    p.kill(); p.wait()
    bad("still running 120 s after SIGTERM: killed")
    sys.exit(1)
err.close()
text = open(csv).read()
rows = text.count("\n") - 1
if text.endswith("\n") and rows > 0: ok(f"the CSV is complete ({rows} poses, the last line whole)")
else: bad(f"the CSV ends in a cut line or has no poses ({rows})")
e = open(os.path.join(work, "err.txt")).read()
m = re.search(r"^summary: .*$", e, re.M)
if not m:
    bad("no summary on stderr although stdout could not take it:\n" + e)
else:
    s = dict(kv.split("=", 1) for kv in m.group(0).split()[1:])
    if int(s["poses"]) == rows: ok(f"summary poses={s['poses']} = the CSV's rows")
    else: bad(f"summary poses={s['poses']}, the CSV has {rows}")
    if s["output_errors"] == "0" and s["csv_lines_lost"] == "0": ok("no output error counted for the dropped status lines")
    else: bad(f"output_errors={s['output_errors']} csv_lines_lost={s['csv_lines_lost']}")
    if int(s["stdout_lines_lost"]) > 0: ok(f"stdout_lines_lost={s['stdout_lines_lost']}")
    else: bad("stdout_lines_lost=0 although nothing could be written")
os.close(r)
sys.exit(1 if fails else 0)
PY
