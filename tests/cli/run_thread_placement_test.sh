#!/usr/bin/env bash
# `sempose run` with pipeline.non_rt_cpu: 1, the stages on core 0 and the output stage `cpu: -1`
# (its own thread), learned appearance on (a worker thread made at setup). Every thread but the
# RT stages must keep off core 0: the appearance worker used to be made before the main thread
# was pinned, so it could run on core 0 beside the RT stages. And `cpu: -1` means any core the
# process may use: the output stage used to inherit the main thread's one core while the run
# printed "unpinned". A non_rt_cpu that does not exist is said. Needs two cores (skipped
# otherwise, exit 77).
set -euo pipefail
bin=${1:?usage: run_thread_placement_test.sh SEMPOSE}
if (( $(nproc) < 2 )); then echo "skip: needs two cores"; exit 77; fi
work=$(mktemp -d); pid=""
trap '[[ -n $pid ]] && kill $pid 2>/dev/null; rm -rf "$work"' EXIT
cat >"$work/run.yaml" <<YAML
scan: {field_w: 320, field_h: 240, max_roi_w: 128, max_roi_h: 128}
sim:
  clock: real
  targets:
    - {texture: {source: lamella}, size: [60, 40], start: [160, 120, 0]}
tracker: {pattern_size_px: 64, roi_size_px: 96, appearance: {enabled: true}}
pipeline: {lock_memory: false, hold_dma_latency: false, stats_period_ms: 100,
           acquisition: {cpu: 0, priority: 0}, correlation: {cpu: 0, priority: 0},
           output: {cpu: -1, priority: 0}, output_on_correlation_thread: false, non_rt_cpu: 1}
output: {poses_csv: $work/poses.csv}
can: {log_file: $work/can.log}
YAML
"$bin" run --config "$work/run.yaml" --duration 30 >"$work/out.txt" 2>"$work/err.txt" &
pid=$!
for _ in $(seq 1 600); do grep -q '^t=' "$work/out.txt" 2>/dev/null && break; sleep 0.05; done
all=$(python3 -c "import os; print(','.join(map(str, sorted(os.sched_getaffinity(0)))))")
fail=0
for task in /proc/$pid/task/*; do
  name=$(cat "$task/comm"); cpus=$(sed -n 's/^Cpus_allowed_list:\t//p' "$task/status")
  case $name in
    sp-acquire|sp-correlate) want=0 ;;
    sp-output) want=$all ;;
    *) want=1 ;;
  esac
  # The kernel prints ranges (0-1); compared as lists.
  got=$(python3 -c "
s=set()
for p in '$cpus'.split(','):
    a,_,b=p.partition('-'); s.update(range(int(a), int(b or a)+1))
print(','.join(map(str, sorted(s))))")
  echo "thread $name: cores $got (want $want)"
  [[ $got == "$want" ]] || fail=1
done
kill $pid; code=0; wait $pid || code=$?; pid=""
if [[ $code != 0 ]]; then echo "FAIL exit $code"; cat "$work/err.txt"; exit 1; fi
if (( fail )); then echo "FAIL a thread is placed where its config does not say"; exit 1; fi
echo "ok   RT stages on core 0, the output stage on every core, the rest on non_rt_cpu 1"
# A non_rt_cpu the machine does not have is said (it used to be left unpinned without a word).
sed -i 's/non_rt_cpu: 1}/non_rt_cpu: 1000}/' "$work/run.yaml"
"$bin" run --config "$work/run.yaml" --duration 0.3 >"$work/out.txt" 2>"$work/err.txt" || { echo "FAIL exit $?"; exit 1; }
if ! grep -q 'warning: pipeline.non_rt_cpu: cannot pin the main thread to cpu 1000' "$work/err.txt"; then
  echo "FAIL non_rt_cpu 1000 not said:"; cat "$work/err.txt"; exit 1
fi
echo "ok   non_rt_cpu 1000: said"
# Started on core 1 only (taskset, a unit's CPUAffinity=) with the stages pinned to core 0: they
# run where the config says, and the run says it is outside the cores it was started on (it went
# unsaid, found probing).
taskset -c 1 "$bin" run --config "$work/run.yaml" --duration 0.3 >"$work/out.txt" 2>"$work/err.txt" || { echo "FAIL exit $?"; exit 1; }
if ! grep -q "thread 'sp-acquire': pinned to cpu 0 as configured, outside the cores the process was started on" "$work/out.txt"; then
  echo "FAIL a stage pinned outside the process's start cores not said:"; grep -E '^warning|^thread' "$work/out.txt"; exit 1
fi
echo "ok   taskset -c 1 with the stages on core 0: said"
# Launched under a real-time policy (`chrt -f 5`, a unit's CPUSchedulingPolicy=): every thread
# inherited SCHED_FIFO 5 — the main loop, the appearance worker and the priority-0 stages —
# while the placement lines said SCHED_OTHER (found probing). Each is SCHED_OTHER now, as its
# config says, and the run says it dropped the launcher's policy.
sed -i 's/non_rt_cpu: 1000}/non_rt_cpu: 1}/' "$work/run.yaml"
if ! chrt -f 5 true 2>/dev/null; then echo "skip: chrt -f 5 not permitted here"; exit 0; fi
chrt -f 5 "$bin" run --config "$work/run.yaml" --duration 30 >"$work/out.txt" 2>"$work/err.txt" &
pid=$!
for _ in $(seq 1 600); do grep -q '^t=' "$work/out.txt" 2>/dev/null && break; sleep 0.05; done
fail=0
for task in /proc/$pid/task/*; do
  name=$(cat "$task/comm"); policy=$(python3 -c "import os; print(os.sched_getscheduler(${task##*/}))")
  echo "thread $name: policy $policy (want 0, SCHED_OTHER)"
  [[ $policy == 0 ]] || fail=1
done
kill $pid; code=0; wait $pid || code=$?; pid=""
if [[ $code != 0 ]]; then echo "FAIL exit $code"; cat "$work/err.txt"; exit 1; fi
if (( fail )); then echo "FAIL a thread runs the launcher's real-time policy"; exit 1; fi
if ! grep -q '^note: started under SCHED_FIFO 5: the main loop and setup.s threads run SCHED_OTHER' "$work/out.txt"; then
  echo "FAIL the launcher's policy not said:"; grep -E '^note|^thread' "$work/out.txt"; exit 1
fi
echo "ok   under chrt -f 5: every thread SCHED_OTHER as configured, said"
