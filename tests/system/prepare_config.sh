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
