#!/bin/bash
# prepare_config.sh SEMPOSE_BINARY CONFIG DEST_DIR DURATION_S
# Fills DEST_DIR with what the target side (guest/guest_test.sh) reads: system.yaml (CONFIG,
# placeholders kept), pattern_gripper.pgm (recorded here from pattern_sim.yaml with
# `sempose sim` + `sempose pattern`) and params.env. Then validates the config with the same
# sempose on this host, so a config error costs a second instead of a VM boot:
#   1. can: -> a candump log, gpio: removed: a 0.5 s run must succeed (exit 0, a summary line);
#   2. the config as written (gpio chip that does not exist here): must get past config
#      validation and fail only when opening the GPIO chip.
set -euo pipefail
SEMPOSE=${1:?usage: prepare_config.sh SEMPOSE CONFIG DEST DURATION}
CONFIG=${2:?}; DEST=${3:?}; DURATION=${4:?}
HERE=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$DEST"
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT

cp "$CONFIG" "$DEST/system.yaml"
"$SEMPOSE" sim --out "$W/frames" --frames 10 --dwell 2000 --config "$HERE/pattern_sim.yaml" > "$W/sim.log" 2>&1 ||
  { cat "$W/sim.log"; echo "prepare_config: sempose sim failed"; exit 1; }
"$SEMPOSE" pattern --frames "$W/frames" --center 256,192 --size 64 --average 10 \
  --out "$DEST/pattern_gripper.pgm" > "$W/pattern.log" 2>&1 ||
  { cat "$W/pattern.log"; echo "prepare_config: sempose pattern failed"; exit 1; }
echo "DURATION=$DURATION" > "$DEST/params.env"

# Preflight 1: the whole pipeline on this host, CAN to a log, no GPIO.
cp "$DEST/pattern_gripper.pgm" "$W/"
sed -e 's|^can:.*|can: {log_file: "@OUT@/sempose_can.log", base_id: 0x100, heartbeat_hz: 10}|' -e '/^gpio:/d' \
    -e 's/priority: [0-9]*/priority: 0/g' \
    -e "s|@OUT@|$W|g" -e 's|@CAN_IF@||g' -e 's|@GPIO_CHIP@||g' "$CONFIG" > "$W/preflight.yaml"
# (priorities 0: this is a build host, not the target)
if ! "$SEMPOSE" run --config "$W/preflight.yaml" --duration 0.5 > "$W/run.log" 2>&1 ||
   ! grep -q '^summary: poses=[1-9]' "$W/run.log"; then
  tail -n 20 "$W/run.log"; echo "prepare_config: preflight run of $CONFIG failed on the host"; exit 1
fi
echo "[prepare_config] host preflight: $(grep '^summary:' "$W/run.log" | cut -c1-90)"
# Preflight 2: the config as the target reads it (only the GPIO chip must be missing here).
sed -e "s|@OUT@|$W|g" -e 's|@CAN_IF@|vcan-none|g' -e 's|@GPIO_CHIP@|sempose-no-such-chip|g' \
    "$CONFIG" > "$W/full.yaml"
rc=0; "$SEMPOSE" run --config "$W/full.yaml" --duration 0.1 > "$W/full.log" 2>&1 || rc=$?
if grep -q "invalid config" "$W/full.log" || ! grep -q "sempose-no-such-chip" "$W/full.log"; then
  cat "$W/full.log"; echo "prepare_config: $CONFIG does not validate (rc $rc)"; exit 1
fi

# The Comedi end-to-end run: sem_emul's scene (the simulator's expected image of scene_sim.yaml),
# its truth, the electrons per sample that match the simulator's noise, and the simulator's own
# accuracy at that dose (`sempose replay` of simulated frames with the same tracker settings),
# which the host check holds the run on the emulated SEM to.
cp "$HERE/system_comedi.yaml" "$DEST/system_comedi.yaml"
sed 's/^  noise: true/  noise: false/' "$HERE/scene_sim.yaml" > "$W/scene_clean.yaml"
"$SEMPOSE" sim --out "$W/scene" --frames 1 --dwell 2000 --config "$W/scene_clean.yaml" > "$W/scene.log" 2>&1 ||
  { cat "$W/scene.log"; echo "prepare_config: sempose sim (scene) failed"; exit 1; }
REF_DWELL_NS=250
"$SEMPOSE" sim --out "$W/ref" --frames 40 --dwell $REF_DWELL_NS --config "$HERE/scene_sim.yaml" > "$W/ref.log" 2>&1 ||
  { cat "$W/ref.log"; echo "prepare_config: sempose sim (reference) failed"; exit 1; }
/usr/bin/python3 "$HERE/make_sem_scene.py" "$W/scene" "$W/ref" "$DEST" || { echo "prepare_config: make_sem_scene.py failed"; exit 1; }
# That dose at the run's first dwell (the governor's initial_dwell_ns); sem_emul scales it with
# the dwell the governor sets, as a real detector does, and the tracker expects.
initial_dwell=$(sed -n 's/.*initial_dwell_ns: *\([0-9]*\).*/\1/p' "$HERE/system_comedi.yaml")
[ -n "$initial_dwell" ] || { echo "prepare_config: no governor initial_dwell_ns in system_comedi.yaml"; exit 1; }
echo "SEM_REF_DWELL_NS=$initial_dwell" >> "$DEST/sem_electrons.env"
sed -e "s|@OUT@|$W|g" -e 's|@CAN_IF@||g' -e 's|@COMEDI_SEM@|/dev/comedi-none|g' "$HERE/system_comedi.yaml" > "$W/comedi.yaml"
"$SEMPOSE" replay --frames "$W/ref" --config "$W/comedi.yaml" --truth "$W/ref/ground_truth.csv" \
  --out "$W/ref_poses.csv" > "$W/ref_replay.log" 2>&1 || { cat "$W/ref_replay.log"; echo "prepare_config: replay of the reference failed"; exit 1; }
truth_line=$(grep '^truth:' "$W/ref_replay.log") || { cat "$W/ref_replay.log"; echo "prepare_config: no truth line from replay"; exit 1; }
echo "$truth_line dwell_ns=$REF_DWELL_NS $(tr "\n" " " < "$DEST/sem_electrons.env")" > "$DEST/sim_reference.txt"
echo "[prepare_config] simulator reference at the emulated SEM's dose: $(cat "$DEST/sim_reference.txt")"
# Preflight of the comedi config: valid, and failing only where the device is missing.
rc=0; "$SEMPOSE" run --config "$W/comedi.yaml" --duration 0.1 > "$W/comedi_run.log" 2>&1 || rc=$?
if grep -q "invalid config" "$W/comedi_run.log" || ! grep -q "cannot open '/dev/comedi-none'" "$W/comedi_run.log"; then
  cat "$W/comedi_run.log"; echo "prepare_config: system_comedi.yaml does not validate (rc $rc)"; exit 1
fi
