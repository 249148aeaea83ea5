#!/usr/bin/env bash
# Hostile inputs on the outside tester's path (sempose sim / pattern / replay) that no other test
# names: each must be a clear error (exit 2, naming the file or option, no output written) or a
# reported status — never a crash, hang or silent wrong output. The scene is the held-out
# needle carrying its lamella over its micrograph's dark chamber.
set -euo pipefail
bin=${1:?usage: hostile_inputs_test.sh SEMPOSE DATA_DIR}
data=$(cd "${2:?usage: hostile_inputs_test.sh SEMPOSE DATA_DIR}" && pwd)
bin=$(readlink -f "$bin")
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
cd "$work"
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }
# expect_error NAME PATTERN OUTPUT_FILE -- CMD...: exit 2, stderr matching PATTERN, OUTPUT_FILE not made.
expect_error() {
  local name=$1 pattern=$2 out=$3; shift 4
  local rc=0; timeout 120 "$@" >"$name.log" 2>&1 || rc=$?
  if [ "$rc" -eq 2 ] && grep -qE "$pattern" "$name.log" && [ ! -e "$out" ]; then ok "$name: exit 2, $(grep -E "$pattern" "$name.log" | head -1)"
  else bad "$name: exit $rc (want 2), output $( [ -e "$out" ] && echo written || echo absent ): $(tail -2 "$name.log")"; fi
}
scene() {  # $1: trajectory
  cat <<YAML
scan: {field_w: 640, field_h: 480, max_roi_w: 256, max_roi_h: 256, min_dwell_ns: 100, max_dwell_ns: 4000}
sim:
  beam_current_pa: 38.46
  background: {source: image, path: $data/needle_lamella_post_eb.pgm, crop: [0, 540, 640, 480]}
  targets:
    - texture: {path: $data/needle_lamella_post_eb.pgm, crop: [40, 380, 360, 190], mask: threshold_all, mask_level: 0.3}
      size: [180, 95]
      brightness: 1.3
      start: [320, 240, 0]
      trajectory: {$1}
YAML
}
scene "kind: static" >still.yaml
scene "kind: sine, amplitude_x_px: 60, amplitude_y_px: 30, amplitude_phi_deg: 15, period_s: 5" >moving.yaml
printf 'scan: {field_w: 640, field_h: 480, max_roi_w: 256, max_roi_h: 256, min_dwell_ns: 100, max_dwell_ns: 4000}\n' >track.yaml
trap 'rc=$?; [ $rc -eq 0 ] || cat "$work/log"; rm -rf "$work"' EXIT
"$bin" sim --out still --frames 10 --dwell 2000 --config still.yaml --seed 11 >log 2>&1
"$bin" pattern --frames still --center 320,240 --size 128 --out p.pgm >>log 2>&1
"$bin" sim --out rec --frames 30 --config moving.yaml >>log 2>&1
frames() { ls "$1"/frame_*.pgm | wc -l; }

# Requests that cannot be met.
expect_error pattern_larger_than_frame "does not fit the 640x480 frames" big.pgm -- "$bin" pattern --frames rec --center 320,240 --size 600 --out big.pgm
"$bin" pattern --frames still --center 320,240 --size 300 --out p300.pgm >>log 2>&1
expect_error pattern_larger_than_roi "larger than tracker.roi_size_px" o1.csv -- "$bin" replay --frames rec --pattern p300.pgm --config track.yaml --out o1.csv
/usr/bin/python3 -c "import sys; open('flat.pgm','wb').write(b'P5\n128 128\n255\n' + bytes([97]) * 16384)"
expect_error flat_pattern "flat" o2.csv -- "$bin" replay --frames rec --pattern flat.pgm --config track.yaml --out o2.csv
mkdir empty
expect_error empty_folder "no \*.pgm frames" o3.csv -- "$bin" replay --frames empty --pattern p.pgm --config track.yaml --out o3.csv

# Recordings that do not hang together.
cp -r rec sizes && /usr/bin/python3 -c "open('sizes/frame_000017.pgm','wb').write(b'P5\n320 240\n255\n' + bytes(320 * 240))"
expect_error replay_frames_of_two_sizes "frame_000017.pgm: size 320x240 differs" o4.csv -- "$bin" replay --frames sizes --pattern p.pgm --config track.yaml --out o4.csv
# The pattern reads frames only while the target stands still: the odd frame goes into the still recording.
cp -r still still_sizes && cp sizes/frame_000017.pgm still_sizes/frame_000005.pgm
expect_error pattern_frames_of_two_sizes "frame_000005.pgm: size 320x240 differs" p4.pgm -- "$bin" pattern --frames still_sizes --center 320,240 --out p4.pgm
# 16-bit frames holding a tiny range (4 grey levels at 1000..1003 of 65535) and 2-bit frames
# (maxval 3): the same scene, quantised away; and one such frame among 8-bit ones.
/usr/bin/python3 - <<'PY'
import glob, os, re, shutil
for name in ("tiny16", "quant2", "depths"):
    os.makedirs(name)
    for p in sorted(glob.glob("rec/frame_*.pgm")):
        d = open(p, "rb").read()
        m = re.match(rb"P5\s+(\d+)\s+(\d+)\s+(\d+)\s", d)
        w, h = int(m.group(1)), int(m.group(2))
        px = d[m.end():m.end() + w * h]
        level = [min(3, v * 4 // 256) for v in px]
        out = os.path.join(name, os.path.basename(p))
        if name == "quant2":
            open(out, "wb").write(b"P5\n%d %d\n3\n" % (w, h) + bytes(level))
        elif name == "tiny16" or p.endswith("frame_000009.pgm"):
            open(out, "wb").write(b"P5\n%d %d\n65535\n" % (w, h) + b"".join((1000 + v).to_bytes(2, "big") for v in level))
        else:
            shutil.copy(p, out)
    for c in ("frames.csv", "ground_truth.csv"):
        shutil.copy("rec/" + c, name)
PY
expect_error replay_frames_of_two_depths "16-bit samples where the first frame has 8-bit" o5.csv -- "$bin" replay --frames depths --pattern p.pgm --config track.yaml --out o5.csv
cp -r still still_depths && cp depths/frame_000009.pgm still_depths/frame_000005.pgm
expect_error pattern_frames_of_two_depths "frame_000005.pgm: 16-bit samples where the first frame has 8-bit" p5.pgm -- "$bin" pattern --frames still_depths --center 320,240 --out p5.pgm
for d in tiny16 quant2; do
  rc=0; timeout 120 "$bin" replay --frames $d --pattern p.pgm --config track.yaml --truth $d/ground_truth.csv --out $d.csv >$d.log 2>&1 || rc=$?
  line=$(grep '^truth:' $d.log || true)
  trk=$(grep -c ',TRACKING,' $d.csv || true)
  if [ "$rc" -eq 0 ] && echo "$line" | grep -q 'false_tracking=0 ' && [ "$trk" -ge 20 ] && ! grep -qiE 'nan|inf' $d.csv; then
    ok "$d frames: $trk of 30 TRACKING, $line"
  else bad "$d frames: exit $rc, $trk TRACKING, $line"; fi
done

# A ground truth with frames missing: the TRACKING poses on them are counted, not left out.
awk -F, 'NR == 1 || $1 < 10 || $1 >= 20' rec/ground_truth.csv >gap.csv
rc=0; "$bin" replay --frames rec --pattern p.pgm --config track.yaml --truth gap.csv --out gap_poses.csv >gap.log 2>&1 || rc=$?
line=$(grep '^truth:' gap.log || true)
gap_trk=$(awk -F, 'NR > 1 && $1 >= 10 && $1 < 20 && $7 == "TRACKING"' gap_poses.csv | wc -l)
if [ "$rc" -eq 0 ] && [ "$gap_trk" -gt 0 ] && echo "$line" | grep -q "tracking_without_truth=$gap_trk\$"; then ok "truth with frames 10-19 missing: $line"
else bad "truth with a gap: exit $rc, $gap_trk TRACKING poses in the gap, $line"; fi

# A recording holding frames 12-15 as copies of frame 11 (a frozen frame buffer while the target
# moved on): replayed as bad frames (LOST), said on stderr; before, 4 TRACKING poses up to 21 px off.
cp -r rec frozen && for f in 12 13 14 15; do cp frozen/frame_000011.pgm frozen/frame_0000$f.pgm; done
rc=0; "$bin" replay --frames frozen --pattern p.pgm --config track.yaml --truth frozen/ground_truth.csv --out frozen.csv >frozen.log 2>&1 || rc=$?
line=$(grep '^truth:' frozen.log || true)
frozen_lost=$(awk -F, 'NR > 1 && $1 >= 12 && $1 <= 15 && $7 == "LOST"' frozen.csv | wc -l)
if [ "$rc" -eq 0 ] && [ "$frozen_lost" -eq 4 ] && grep -q "4 frame(s) repeat the frame before" frozen.log && echo "$line" | grep -q 'false_tracking=0 '; then
  ok "frozen frames 12-15: LOST, with a warning; $line"
else bad "frozen frames: exit $rc, $frozen_lost of 4 LOST, $line: $(grep warning frozen.log)"; fi

# A pattern made from a moving recording: averaged over the first frame only, said on stderr.
rc=0; "$bin" pattern --frames rec --center 320,240 --size 128 --out moving.pgm >moving.log 2>&1 || rc=$?
if [ "$rc" -eq 0 ] && grep -q "the target moves or turns" moving.log && grep -q "mean of 1 frames" moving.log; then ok "pattern from a moving target: one frame, with a warning"
else bad "pattern from a moving target: exit $rc: $(cat moving.log)"; fi

[ "$fails" -eq 0 ] && echo "heldout_hostile_inputs: all passed" || { echo "heldout_hostile_inputs: $fails failed"; exit 1; }
