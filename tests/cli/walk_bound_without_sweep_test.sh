#!/usr/bin/env bash
# An angle the walk left at its per-frame bound with no recovery sweep around it (hostile round
# 12): `tracker: {max_angle_steps_per_frame: 1, recover_sweep_deg: 0}` (both in range) on a
# needle tip spinning 400°/s (~4° a ROI frame) followed the spin at the walk's bound, short of
# the target's angle frame after frame, and 4 poses were TRACKING 10.6-14.8° off on σφ 1.6-2.7°.
# Such a pose is UNCERTAIN; with the default sweep the spin stays TRACKING.
set -euo pipefail
bin=${1:?usage: walk_bound_without_sweep_test.sh SEMPOSE SOURCE_DIR}
src=$(cd "${2:?usage: walk_bound_without_sweep_test.sh SEMPOSE SOURCE_DIR}" && pwd)
work=$(mktemp -d); [ -n "${KEEP:-}" ] || trap 'rm -rf "$work"' EXIT; echo "work: $work"
field='scan: {field_w: 320, field_h: 240, max_roi_w: 200, max_roi_h: 200, min_dwell_ns: 100, max_dwell_ns: 4000}'
scene() {
  printf '%s\nsim:\n  seed: 4\n  targets:\n    - texture: {path: %s, crop: [552, 430, 120, 160], mask: threshold, mask_level: 0.5}\n      size: [90, 120]\n      start: [160, 120, 0]\n      trajectory: {%s}\n' \
    "$field" "$src/config/data/sem/needle_contact_eb.pgm" "$1"
}
scene "kind: static" >"$work/still.yaml"
scene "kind: spin, omega_deg_s: 400" >"$work/spin.yaml"
"$bin" sim --out "$work/still" --frames 10 --dwell 2000 --config "$work/still.yaml" >"$work/log" 2>&1
"$bin" pattern --frames "$work/still" --center 160,120 --size 128 --out "$work/p.pgm" >>"$work/log" 2>&1
"$bin" sim --out "$work/rec" --frames 80 --dwell 250 --config "$work/spin.yaml" >>"$work/log" 2>&1
fail=0
for tracker in "max_angle_steps_per_frame: 1, recover_sweep_deg: 0" "max_angle_steps_per_frame: 2, recover_sweep_deg: 0" \
               "max_angle_steps_per_frame: 1"; do
  printf '%s\ntracker: {roi_size_px: 192, %s}\npipeline: {virtual_compute_ns: 200000}\n' "$field" "$tracker" >"$work/t.yaml"
  out=$("$bin" replay --frames "$work/rec" --pattern "$work/p.pgm" --config "$work/t.yaml" --truth "$work/rec/ground_truth.csv" \
          --out "$work/poses.csv" 2>>"$work/log") || { cat "$work/log"; echo "FAIL sempose replay ($tracker)"; exit 1; }
  line=$(grep '^truth:' <<<"$out")
  echo "tracker {$tracker}: $line"
  compared=$(sed -E 's/.*poses_compared=([0-9]+).*/\1/' <<<"$line")
  false_n=$(sed -E 's/.*false_tracking=([0-9]+).*/\1/' <<<"$line")
  [ "$false_n" -eq 0 ] || { echo "FAIL: $false_n TRACKING poses > 3 px or > 10° off with {$tracker}"; fail=1; }
  # With the default sweep the spin is followed and TRACKING on most of its 80 frames.
  if [[ $tracker != *recover_sweep_deg* ]] && [ "$compared" -lt 60 ]; then
    echo "FAIL: only $compared of 80 frames TRACKING with the default sweep"; fail=1
  fi
done
[ "$fail" -eq 0 ] && echo "PASS"
exit "$fail"
