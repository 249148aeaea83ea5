#!/usr/bin/env bash
# The operator's view end to end: record a simulated sequence (`sempose sim`, a gripper on a
# figure eight), make its pattern (`sempose pattern`), track it (`sempose replay`), then
# `sempose view` must write the pose plot and every Nth ROI as a PNG of the ROI's size, and
# name a bad input (missing frames folder, wrong --pattern count) without writing anything.
set -euo pipefail
bin=${1:?usage: view_replay_test.sh SEMPOSE}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }
cat >"$work/static.yaml" <<'YAML'
scan: {field_w: 512, field_h: 384, max_roi_w: 192, max_roi_h: 192}
sim:
  seed: 3
  targets:
    - texture: {source: gripper}
      size: [96, 72]
      start: [256, 192, 0]
      trajectory: {kind: static}
YAML
sed -e 's/kind: static}/kind: sine, amplitude_x_px: 60, amplitude_y_px: 30, amplitude_phi_deg: 20, period_s: 4}/' \
  "$work/static.yaml" >"$work/moving.yaml"
"$bin" sim --out "$work/still" --frames 10 --dwell 2000 --config "$work/static.yaml" >"$work/log" 2>&1
"$bin" pattern --frames "$work/still" --center 256,192 --size 96 --average 10 --out "$work/gripper.pgm" >>"$work/log" 2>&1
"$bin" sim --out "$work/rec" --frames 30 --dwell 500 --config "$work/moving.yaml" >>"$work/log" 2>&1
"$bin" replay --frames "$work/rec" --pattern "$work/gripper.pgm" --out "$work/poses.csv" >>"$work/log" 2>&1 \
  || { cat "$work/log"; bad "recording and replay"; }

rc=0; "$bin" view --poses "$work/poses.csv" --frames "$work/rec" --pattern "$work/gripper.pgm" --every 10 --roi 160 \
  --out "$work/view" >"$work/view.txt" 2>&1 || rc=$?
cat "$work/view.txt"
[ "$rc" -eq 0 ] && ok "sempose view exit 0" || bad "sempose view exit $rc"
file_type() { head -c 8 "$1" | od -An -tx1 | tr -d ' \n'; }
[ -s "$work/view/track.png" ] && [ "$(file_type "$work/view/track.png")" = 89504e470d0a1a0a ] \
  && ok "track.png is a PNG" || bad "track.png missing or not a PNG"
n=$(ls "$work/view"/roi_*.png 2>/dev/null | wc -l)
[ "$n" -eq 3 ] && ok "3 ROI pictures for 30 poses, every 10th" || bad "$n ROI pictures"
# IHDR: width and height at bytes 16..23: 160 px ROI x scale 2 = 320.
dims=$(od -An -tu1 -j16 -N8 "$work/view/roi_000000.png" | awk '{print $3*256+$4 "x" $7*256+$8}')
[ "$dims" = 320x320 ] && ok "ROI picture 320x320 (160 px ROI, scale 2)" || bad "ROI picture $dims"

# The same folder again with fewer pictures (every 20th): the earlier view's third picture is
# not this view's and is removed, said (it stayed among the new ones, found probing).
rc=0; "$bin" view --poses "$work/poses.csv" --frames "$work/rec" --pattern "$work/gripper.pgm" --every 20 --roi 160 \
  --out "$work/view" >"$work/view_again.txt" 2>&1 || rc=$?
n=$(ls "$work/view"/roi_*.png 2>/dev/null | wc -l)
[ "$rc" -eq 0 ] && [ "$n" -eq 2 ] && grep -q "removed 1 ROI picture(s) an earlier view left" "$work/view_again.txt" \
  && ok "an earlier view's extra ROI picture removed, said" || { cat "$work/view_again.txt"; bad "view again: rc $rc, $n pictures"; }

# A run's CSV (two targets, target index column): the plot alone, one line per target.
cat >"$work/run.yaml" <<YAML
sim: {clock: virtual, targets: [{texture: {source: gripper}, size: [96, 72], start: [300, 300, 0]},
                                {texture: {source: lamella}, size: [80, 60], start: [700, 400, 30]}]}
pipeline: {acquisition: {cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0}, output: {cpu: -1, priority: 0}, lock_memory: false, hold_dma_latency: false}
output: {poses_csv: $work/run_poses.csv, print_status: false}
can: {log_file: $work/run_can.log}
YAML
"$bin" run --config "$work/run.yaml" --duration 2 >"$work/run.log" 2>&1 || { tail -5 "$work/run.log"; bad "sempose run for a CSV"; }
rc=0; "$bin" view --poses "$work/run_poses.csv" --out "$work/runview" >"$work/runview.txt" 2>&1 || rc=$?
cat "$work/runview.txt"
[ "$rc" -eq 0 ] && grep -q "2 target(s)" "$work/runview.txt" && [ -s "$work/runview/track.png" ] && grep -q "index 1" "$work/runview/track.gp" \
  && ok "run CSV: plot of both targets" || bad "run CSV view: rc $rc"

rc=0; "$bin" view --poses "$work/poses.csv" --frames "$work/nope" --out "$work/view2" >"$work/e1.txt" 2>&1 || rc=$?
[ "$rc" -eq 2 ] && grep -q "nope" "$work/e1.txt" && [ ! -e "$work/view2" ] && ok "missing frames folder: named, exit 2, nothing written" \
  || { cat "$work/e1.txt"; bad "missing frames folder: rc $rc"; }
rc=0; "$bin" view --poses "$work/poses.csv" --pattern a.pgm --pattern b.pgm --out "$work/view3" >"$work/e2.txt" 2>&1 || rc=$?
[ "$rc" -eq 2 ] && grep -q "2 --pattern for 1 target" "$work/e2.txt" && ok "pattern count checked" || { cat "$work/e2.txt"; bad "pattern count: rc $rc"; }
[ "$fails" -eq 0 ] && echo "view_replay: all passed" || { echo "view_replay: $fails failed"; exit 1; }
