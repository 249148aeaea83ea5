#!/usr/bin/env bash
# `sempose run` with its standard output a pipe nobody reads any more (`sempose run … | head
# -1`, a monitoring script that exited). The controller must keep running and end as it would
# otherwise: not killed by SIGPIPE (before: signal 13 at the first status flush, the CSV and
# the candump log cut short, no summary). (`run` refuses poses_csv "-": its stdout carries the
# status.) No timing: the pipe's read end is closed before sempose starts.
set -euo pipefail
bin=${1:?usage: run_closed_stdout_test.sh SEMPOSE}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }
. "$(dirname "$0")/small_run_config.sh"
config() { small_run_config "$1" "$work/can.log"; }  # $1: output.poses_csv
# Runs sempose with stdout the write end of a pipe whose read end is already closed; prints
# the exit code (negative: killed by that signal). SIGPIPE is left at its default in the child.
closed_stdout() {
  python3 - "$@" <<'PY'
import os, subprocess, sys
r, w = os.pipe()
os.close(r)
p = subprocess.run(sys.argv[1:], stdout=w, stderr=open(os.environ["ERR"], "w"), timeout=120)
print(p.returncode)
PY
}

config "$work/poses.csv" >"$work/file.yaml"
code=$(ERR="$work/err1.txt" closed_stdout "$bin" run --config "$work/file.yaml" --duration 1)
if [[ $code == 0 ]]; then ok "CSV to a file, stdout closed: exit 0"; else bad "CSV to a file, stdout closed: exit $code (-13: killed by SIGPIPE)"; cat "$work/err1.txt"; fi
lines=$(wc -l <"$work/poses.csv" || echo 0)
if [[ $lines -gt 10 ]] && [[ $(tail -c1 "$work/poses.csv" | od -An -c | tr -d ' ') == '\n' ]]; then
  ok "the CSV is complete ($lines lines, the last one whole)"
else
  bad "the CSV has $lines lines or ends in a cut line"
fi
if [[ -s "$work/can.log" ]]; then ok "the candump log was written"; else bad "the candump log is empty"; fi

exit $((fails > 0))
