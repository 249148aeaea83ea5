#!/usr/bin/env bash
# `sempose replay` runs the same path as `sempose run`: record a simulated sequence with two
# moving targets (`sempose sim`), make their patterns (`sempose pattern`), track the recording
# with `sempose run` (source: replay, virtual clock: the RT pipeline on its threads) and with
# `sempose replay` (the offline runner), and the two CSVs must be the same file, byte for byte:
# same columns, target index, scan-end time stamps and bit-identical poses (printed %.4f).
set -euo pipefail
bin=${1:?usage: replay_matches_run_test.sh SEMPOSE}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }
scene() {  # $1: trajectory of both targets
  cat <<YAML
scan: {field_w: 512, field_h: 384, max_roi_w: 160, max_roi_h: 160, min_dwell_ns: 250, max_dwell_ns: 2000}
sim:
  seed: 5
  targets:
    - texture: {source: gripper}
      size: [96, 72]
      start: [160, 150, 0]
      trajectory: {kind: $1}
    - texture: {source: lamella}
      size: [80, 60]
      start: [360, 250, 20]
      trajectory: {kind: $1}
YAML
}
scene static >"$work/still.yaml"
scene "sine, amplitude_x_px: 40, amplitude_y_px: 20, amplitude_phi_deg: 15, period_s: 3" >"$work/moving.yaml"
"$bin" sim --out "$work/still" --frames 10 --dwell 2000 --config "$work/still.yaml" >"$work/log" 2>&1
"$bin" pattern --frames "$work/still" --center 160,150 --size 96 --average 10 --out "$work/gripper.pgm" >>"$work/log" 2>&1
"$bin" pattern --frames "$work/still" --center 360,250 --size 96 --average 10 --out "$work/lamella.pgm" >>"$work/log" 2>&1
"$bin" sim --out "$work/rec" --frames 60 --dwell 500 --config "$work/moving.yaml" >>"$work/log" 2>&1

# The pipeline: its threads unprivileged and unpinned, a modelled compute time so the
# governor's dwell (and so every scan-end time) does not depend on this machine's load.
cat >"$work/run.yaml" <<YAML
source: replay
scan: {field_w: 512, field_h: 384, max_roi_w: 160, max_roi_h: 160, min_dwell_ns: 250, max_dwell_ns: 2000}
replay: {frames_dir: $work/rec, clock: virtual}
targets:
  - {name: gripper, pattern_sets: [{file: $work/gripper.pgm}]}
  - {name: lamella, pattern_sets: [{file: $work/lamella.pgm}]}
tracker: {pattern_size_px: 96, roi_size_px: 160}
pipeline:
  acquisition: {cpu: -1, priority: 0}
  correlation: {cpu: -1, priority: 0}
  output: {cpu: -1, priority: 0}
  lock_memory: false
  hold_dma_latency: false
  virtual_compute_ns: 300000
output: {poses_csv: $work/run.csv, print_status: false}
can: {log_file: $work/run_can.log}
YAML
"$bin" run --config "$work/run.yaml" --duration 120 >"$work/run.log" 2>&1 || { cat "$work/log" "$work/run.log"; bad "sempose run on the recording"; }
grep -q "the source ended" "$work/run.log" && ok "sempose run tracked the whole recording" || bad "sempose run did not reach the recording's end"
"$bin" replay --frames "$work/rec" --config "$work/run.yaml" --out "$work/replay.csv" >"$work/replay.log" 2>&1 \
  || { cat "$work/replay.log"; bad "sempose replay on the recording"; }
cat "$work/replay.log"

lines=$(wc -l <"$work/replay.csv")
[ "$lines" -eq 61 ] && ok "replay: 60 poses (one per recorded frame) + header" || bad "replay: $lines lines"
head -1 "$work/replay.csv" | grep -qx 'frame,t_ns,x_px,y_px,phi_deg,score,status,target,scale,sigma_x_px,sigma_y_px,sigma_phi_deg,sigma_scale,angle_order' && ok "pipeline's columns" || bad "header: $(head -1 "$work/replay.csv")"
tracking=$(grep -c ',TRACKING,' "$work/replay.csv" || true)
[ "$tracking" -ge 50 ] && ok "$tracking TRACKING poses (a comparison of real poses, not of two empty tracks)" || bad "only $tracking TRACKING poses"
for t in 0 1; do
  n=$(awk -F, -v t=$t 'NR > 1 && $8 == t' "$work/replay.csv" | wc -l)
  [ "$n" -eq 30 ] && ok "target $t: 30 poses" || bad "target $t: $n poses"
done
if cmp "$work/run.csv" "$work/replay.csv"; then
  ok "sempose run and sempose replay wrote the same CSV ($lines lines)"
else
  diff "$work/run.csv" "$work/replay.csv" | head -10 || true
  bad "the CSVs differ"
fi
# The same recording with the default thread placement: both RT stages SCHED_FIFO on one
# core, acquisition above correlation. The lock-step wait of the acquisition once woke every
# 5 µs and left correlation ~1 % of the core (one pose in 5 s); the recording must end well
# within the time limit. Without RT privileges the stages run SCHED_OTHER (said below).
sed -e '/^pipeline:/,/^  virtual_compute_ns/{/^pipeline:/!{/virtual_compute_ns/!d}}' "$work/run.yaml" >"$work/run_default.yaml"
sed -i -e "s#$work/run.csv#$work/run_default.csv#; s#$work/run_can.log#$work/run_default_can.log#" "$work/run_default.yaml"
timeout 100 "$bin" run --config "$work/run_default.yaml" --duration 60 >"$work/run_default.log" 2>&1 || true
grep -E '^thread (acquisition|correlation)' "$work/run_default.log" || true
if grep -q "the source ended" "$work/run_default.log" && cmp -s "$work/run.csv" "$work/run_default.csv"; then
  ok "default placement: sempose run tracked the whole recording, the same CSV"
else
  tail -n 5 "$work/run_default.log"; bad "default placement: the recording did not end in 60 s or its CSV differs"
fi
[ "$fails" -eq 0 ] && echo "replay_matches_run: all passed" || { echo "replay_matches_run: $fails failed"; exit 1; }
