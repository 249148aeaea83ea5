#!/usr/bin/env bash
# `sempose run` stopped for 1.5 s (SIGSTOP, a suspended VM or a debugger), then continued. Its
# status line comes once per stats period of the time it ran: before, it caught up every missed
# period at once (after a 5 s stop, 10 lines of the same t=… in a burst into the journal). Not
# timed: the line count can only fall under load (a late loop prints fewer lines), and the stop
# is at least 1.5 s whatever the machine does.
set -euo pipefail
bin=${1:?usage: run_time_jump_test.sh SEMPOSE}
work=$(mktemp -d); pid=""
trap '[[ -n $pid ]] && kill -CONT $pid 2>/dev/null; rm -rf "$work"' EXIT
. "$(dirname "$0")/small_run_config.sh"
small_run_config "$work/poses.csv" "$work/can.log" >"$work/run.yaml"
"$bin" run --config "$work/run.yaml" --duration 4 >"$work/out.txt" 2>"$work/err.txt" &
pid=$!
# Stop it once it prints its first status line (it runs), for 1.5 s.
for _ in $(seq 1 600); do grep -q '^t=' "$work/out.txt" 2>/dev/null && break; sleep 0.05; done
kill -STOP $pid
t_stop=$(date +%s.%N)
sleep 1.5
t_cont=$(date +%s.%N)
kill -CONT $pid
code=0; wait $pid || code=$?; pid=""
lines=$(grep -c '^t=' "$work/out.txt" || true)
stopped=$(python3 -c "print(round($t_cont - $t_stop, 2))")
# 4 s run, >= 1.5 s of it stopped: at most 2.5 s / 0.1 s = 25 periods ran, +2 for the edges.
limit=27
echo "exit $code, $lines status lines in a 4 s run stopped for $stopped s (at most $limit)"
if [[ $code != 0 ]]; then echo "FAIL exit $code"; cat "$work/err.txt"; exit 1; fi
if (( lines > limit )); then
  echo "FAIL the status lines of the stopped periods came in a burst:"; grep '^t=' "$work/out.txt" | cut -c1-40
  exit 1
fi
echo "ok   one status line per period run"
