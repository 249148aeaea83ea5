#!/usr/bin/env bash
# A lost target re-found on another object (hostile round 13, F2): the needle tip leaves the
# field across its right edge and comes back while another micrograph's needle (not a copy:
# another surface, another end) stands still elsewhere. The search after the loss took that
# needle, turned ~155°, at 0.60-0.65 where the tip scored 0.85, and kept it TRACKING while the
# tip came back: 38 of 120 poses false. The share of the attainable score it explains (0.66-0.71
# against the tip's 0.90-0.92) keeps it UNCERTAIN, and the field searched again while it is
# followed finds the tip when it is back (Tracker::Impl::check_refind_level).
set -euo pipefail
bin=${1:?usage: another_object_after_loss_test.sh SEMPOSE SOURCE_DIR}
src=$(cd "${2:?usage: another_object_after_loss_test.sh SEMPOSE SOURCE_DIR}" && pwd)
work=$(mktemp -d); [ -n "${KEEP:-}" ] || trap 'rm -rf "$work"' EXIT; echo "work: $work"
sem=$src/config/data/sem
tip="{source: image, path: $sem/needle_contact_eb.pgm, crop: [552, 430, 120, 160], mask: threshold}, size: [90, 120]"
other="{source: image, path: $sem/needle_lamella_post_eb.pgm, crop: [60, 370, 130, 180], mask: threshold, mask_level: 0.15}, size: [90, 120]"
field='scan: {field_w: 640, field_h: 480, max_roi_w: 256, max_roi_h: 256}'
printf '%s\nsim:\n  clock: virtual\n  targets:\n    - {texture: %s, start: [200, 240, 0]}\n' "$field" "$tip" >"$work/still.yaml"
cat >"$work/scene.yaml" <<YAML
$field
sim:
  clock: virtual
  targets:
    - {texture: $tip, start: [200, 120, 0], trajectory: {kind: sine, amplitude_x_px: 450, amplitude_y_px: 0, amplitude_phi_deg: 0, period_s: 8}}
    - {texture: $other, start: [400, 360, 0]}
YAML
"$bin" sim --out "$work/still" --frames 10 --config "$work/still.yaml" --dwell 2000 >"$work/log" 2>&1
"$bin" pattern --frames "$work/still" --center 200,240 --size 128 --out "$work/needle.pgm" >>"$work/log" 2>&1
"$bin" sim --out "$work/scene" --frames 120 --config "$work/scene.yaml" >>"$work/log" 2>&1
"$bin" replay --frames "$work/scene" --pattern "$work/needle.pgm" --out "$work/poses.csv" >>"$work/log" 2>&1 ||
  { cat "$work/log"; echo "FAIL sempose replay"; exit 1; }
# Against target 0's truth (the tip): no TRACKING pose > 3 px or > 10° off, none while the tip is
# out of the field, and the tip TRACKING again on most frames it is wholly back in the field.
/usr/bin/python3 - "$work/poses.csv" "$work/scene/ground_truth.csv" <<'PY'
import csv, math, sys
truth = {int(r['frame']): r for r in csv.DictReader(open(sys.argv[2])) if r['target'] == '0'}
false = without = back = back_tracked = 0
exited = False
for p in csv.DictReader(open(sys.argv[1])):
    f = int(p['frame'])
    t = truth.get(f)
    tracking = p['status'] == 'TRACKING'
    if t is None:  # the tip is outside the field
        exited = True
        without += tracking
        continue
    dx, dy = float(p['x_px']) - float(t['x_px']), float(p['y_px']) - float(t['y_px'])
    dphi = abs((float(p['phi_deg']) - float(t['phi_deg']) + 180) % 360 - 180)
    on_tip = math.hypot(dx, dy) <= 3 and dphi <= 10
    false += tracking and not on_tip
    if exited and 100 <= float(t['x_px']) <= 540:
        back += 1
        back_tracked += tracking and on_tip
print(f"false TRACKING {false}, TRACKING without the tip {without}, tip back {back} frames, TRACKING on it {back_tracked}")
fails = []
if false: fails.append(f"{false} TRACKING poses > 3 px or > 10 deg from the tip (38 before the fix)")
if without: fails.append(f"{without} TRACKING poses while the tip was out of the field (23 before the fix)")
if back < 30: fails.append(f"the scene brought the tip back on {back} frames only")
elif back_tracked < back // 2: fails.append(f"the tip back in the field TRACKING on {back_tracked} of {back} frames: not found again")
for m in fails: print("FAIL", m)
sys.exit(1 if fails else 0)
PY
echo PASS
