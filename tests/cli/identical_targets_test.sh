#!/usr/bin/env bash
# Two targets with one pattern (two identical needle tips in the field, the pattern recorded
# from one of them): each target must hold its own object. Before the start search skipped
# the places the run's other targets hold, target 1 found the same needle as target 0 and
# reported it TRACKING — a pose of the wrong object.
set -euo pipefail
bin=${1:?usage: identical_targets_test.sh SEMPOSE SOURCE_DIR}
src=${2:?usage: identical_targets_test.sh SEMPOSE SOURCE_DIR}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
scene() {  # $1: trajectory of both needles
  cat <<YAML
scan: {field_w: 640, field_h: 480, max_roi_w: 256, max_roi_h: 256, min_dwell_ns: 250, max_dwell_ns: 2000}
sim:
  seed: 5
  targets:
    - texture: {path: $src/config/data/sem/needle_contact_eb.pgm, crop: [552, 430, 120, 160], mask: threshold, mask_level: 0.5}
      size: [90, 120]
      start: [180, 200, 0]
      trajectory: {kind: $1}
    - texture: {path: $src/config/data/sem/needle_contact_eb.pgm, crop: [552, 430, 120, 160], mask: threshold, mask_level: 0.5}
      size: [90, 120]
      start: [450, 280, 30]
      trajectory: {kind: $1}
YAML
}
scene static >"$work/still.yaml"
scene "sine, amplitude_x_px: 30, amplitude_y_px: 15, amplitude_phi_deg: 10, period_s: 4" >"$work/moving.yaml"
"$bin" sim --out "$work/still" --frames 10 --dwell 2000 --config "$work/still.yaml" >"$work/log" 2>&1
"$bin" pattern --frames "$work/still" --center 180,200 --size 128 --out "$work/needle.pgm" >>"$work/log" 2>&1
cp "$work/needle.pgm" "$work/needle_too.pgm"
"$bin" sim --out "$work/rec" --frames 40 --dwell 500 --config "$work/moving.yaml" >>"$work/log" 2>&1
printf 'scan: {field_w: 640, field_h: 480, max_roi_w: 256, max_roi_h: 256, min_dwell_ns: 250, max_dwell_ns: 2000}\n' >"$work/track.yaml"
"$bin" replay --frames "$work/rec" --pattern "$work/needle.pgm" --pattern "$work/needle_too.pgm" --config "$work/track.yaml" \
  --out "$work/poses.csv" >>"$work/log" 2>&1 || { cat "$work/log"; echo "FAIL sempose replay"; exit 1; }
# Per target: which needle (ground truth's target column) each TRACKING pose is within 3 px
# of, the orientation relative to that needle's at frame 0 (the pattern's). Both must be
# followed, each on one needle only, and not the same one.
/usr/bin/python3 - "$work/poses.csv" "$work/rec/ground_truth.csv" <<'PY'
import csv, math, sys
poses = list(csv.DictReader(open(sys.argv[1])))
truth = {}
for r in csv.DictReader(open(sys.argv[2])):
    truth[(int(r['frame']), int(r['target']))] = (float(r['x_px']), float(r['y_px']))
held, fails = {0: set(), 1: set()}, 0
count = {0: 0, 1: 0}
for p in poses:
    if p['status'] != 'TRACKING':
        continue
    t, f = int(p['target']), int(p['frame'])
    x, y = float(p['x_px']), float(p['y_px'])
    near = [n for n in (0, 1) if (f, n) in truth and math.hypot(x - truth[(f, n)][0], y - truth[(f, n)][1]) < 3]
    count[t] += 1
    if not near:
        print(f"FAIL frame {f}: target {t} TRACKING at ({x:.1f}, {y:.1f}), on neither needle"); fails += 1
    held[t].update(near)
for t in (0, 1):
    if count[t] < 15:
        print(f"FAIL target {t}: {count[t]} TRACKING poses of 20"); fails += 1
    if len(held[t]) != 1:
        print(f"FAIL target {t} held needles {sorted(held[t])}"); fails += 1
if held[0] and held[0] == held[1]:
    print(f"FAIL both targets hold needle {sorted(held[0])}"); fails += 1
print(f"target 0: {count[0]} TRACKING on needle {sorted(held[0])}; target 1: {count[1]} on needle {sorted(held[1])}")
sys.exit(1 if fails else 0)
PY
echo "identical_targets: passed"
