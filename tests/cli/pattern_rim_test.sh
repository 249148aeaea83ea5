#!/usr/bin/env bash
# `sempose pattern`, `replay` and `run` say when a pattern's position information lies at its
# rim (pattern_rim.hpp): the procedural lamella 60 px long recorded in a 64 px window reaches the
# rim along x and is named (at setup of replay and run too, naming the target and the set); the
# same lamella in a 96 px window, and a shorter one in 64 px, are not. Real frames of the
# simulated SEM through the real commands.
set -euo pipefail
bin=${1:?usage: pattern_rim_test.sh SEMPOSE}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }
scene() {  # $1: the lamella's size
  cat <<YAML
scan: {field_w: 320, field_h: 240, max_roi_w: 192, max_roi_h: 192}
sim:
  seed: 4
  targets:
    - {texture: {source: lamella}, size: [$1], start: [160, 120, 0], trajectory: {kind: static}}
YAML
}
record() {  # name size window -> $work/name.pgm, the command's stderr in $work/name.err
  local name=$1 size=$2 window=$3
  scene "$size" >"$work/$name.yaml"
  "$bin" sim --out "$work/$name" --frames 6 --config "$work/$name.yaml" --dwell 2000 >/dev/null 2>&1 ||
    { bad "$name: sempose sim failed"; return 1; }
  "$bin" pattern --frames "$work/$name" --center 160,120 --size "$window" --average 6 --out "$work/$name.pgm" \
    >/dev/null 2>"$work/$name.err" || { bad "$name: sempose pattern failed: $(cat "$work/$name.err")"; return 1; }
}
record rim "60, 40" 64 && {
  if grep -q "warning: .*rim.pgm: [0-9]* % of its position information along x lies in its outer 4 px" "$work/rim.err"; then
    ok "pattern: a lamella reaching the rim is named along x"
  else
    bad "pattern: no rim warning for the lamella 60 px long in 64 px: $(cat "$work/rim.err")"
  fi
  "$bin" replay --frames "$work/rim" --pattern "$work/rim.pgm" --out "$work/rim.csv" >/dev/null 2>"$work/replay.err" ||
    bad "replay failed: $(cat "$work/replay.err")"
  if grep -q "warning: target rim: tracker: warning: pattern set 0: .* along x lies in its outer 4 px" "$work/replay.err"; then
    ok "replay: the target and its set are named at setup"
  else
    bad "replay: no rim warning at setup: $(cat "$work/replay.err")"
  fi
  cat >"$work/run.yaml" <<YAML
source: replay
replay: {frames_dir: $work/rim, loop: true}
targets: [{name: lam, pattern_sets: [{file: $work/rim.pgm}]}]
scan: {max_roi_w: 192, max_roi_h: 192}
tracker: {pattern_size_px: 64, roi_size_px: 96}
pipeline: {acquisition: {cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0}, output: {cpu: -1, priority: 0}, non_rt_cpu: -1, lock_memory: false, hold_dma_latency: false}
output: {poses_csv: $work/run/poses.csv}
can: {log_file: $work/run/can.log}
YAML
  mkdir -p "$work/run"
  timeout 60 "$bin" run --config "$work/run.yaml" --duration 0.3 >"$work/run.out" 2>&1 || bad "run failed: $(tail -5 "$work/run.out")"
  if grep -q "^warning: target lam: tracker: warning: pattern set 0: .* along x" "$work/run.out"; then
    ok "run: the target and its set are named at setup"
  else
    bad "run: no rim warning at setup: $(grep -i warn "$work/run.out" || true)"
  fi
}
for case in "margin 60,40 96" "short 36,24 64"; do
  read -r name size window <<<"$case"
  record "$name" "${size/,/, }" "$window" || continue
  if grep -q "position information" "$work/$name.err"; then
    bad "$name: a pattern with the target inside it was named: $(cat "$work/$name.err")"
  else
    ok "$name: lamella $size in a $window px window: no rim warning"
  fi
done
[ "$fails" -eq 0 ] || { echo "$fails check(s) failed"; exit 1; }
echo "all checks passed"
