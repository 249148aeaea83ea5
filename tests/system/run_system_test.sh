#!/bin/bash
# run_system_test.sh SEMPOSE_BINARY OUT_DIR
# The sempose system test (issue 7): boots Debian's PREEMPT_RT kernel in QEMU (TCG), brings
# up vcan0 + a gpio-sim chip, runs candump / cyclictest / sempose inside, copies the
# artifacts out over a second serial port and checks them on the host (check_results.py).
# Exit: 0 pass, 1 fail, 77 skip (only when qemu cannot start at all).
# Env: SEMPOSE_SYSTEM_CACHE (default /var/cache/sempose-system-test), SEMPOSE_SYSTEM_DURATION
#      (s, default 5), SEMPOSE_SYSTEM_CONFIG (guest config, default tests/system/system.yaml),
#      SEMPOSE_SYSTEM_ARGS (extra `sempose run` args, default "--can-log /out/sempose_can.log"),
#      SEMPOSE_DBC (default ipc/sempose.dbc), SEMPOSE_SYSTEM_BOOTS (attempts, default 3).
set -uo pipefail
SEMPOSE=${1:?usage: run_system_test.sh SEMPOSE_BINARY OUT_DIR}
OUT=${2:?usage: run_system_test.sh SEMPOSE_BINARY OUT_DIR}
HERE=$(cd "$(dirname "$0")" && pwd)
SRC=$(cd "$HERE/../.." && pwd)
CACHE=${SEMPOSE_SYSTEM_CACHE:-/var/cache/sempose-system-test}
DURATION=${SEMPOSE_SYSTEM_DURATION:-5}
CONFIG=${SEMPOSE_SYSTEM_CONFIG:-$HERE/system.yaml}
ARGS=${SEMPOSE_SYSTEM_ARGS---can-log /out/sempose_can.log}
DBC=${SEMPOSE_DBC:-$SRC/ipc/sempose.dbc}
BOOTS=${SEMPOSE_SYSTEM_BOOTS:-3}
PY=/usr/bin/python3
T0=$(date +%s)
log() { echo "[system-test +$(( $(date +%s) - T0 ))s] $*"; }

QEMU=$(command -v qemu-system-x86_64 || true)
if [ -z "$QEMU" ] || ! echo quit | timeout 30 "$QEMU" -machine none -accel tcg -display none \
       -nodefaults -monitor stdio >/dev/null 2>&1; then
  echo "SKIP: qemu-system-x86_64 cannot start here (apt-get install qemu-system-x86)"; exit 77
fi

mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)
rm -rf "$OUT"/attempt-* "$OUT/artifacts" "$OUT/guest-cfg"
mkdir -p "$OUT/guest-cfg" "$OUT/artifacts"

log "prepare host cache $CACHE"
if ! "$HERE/prepare_host.sh" "$CACHE" > "$OUT/prepare.log" 2>&1; then
  tail -n 30 "$OUT/prepare.log"; echo "FAIL: host preparation failed (see $OUT/prepare.log)"; exit 1
fi
grep '^\[prepare\]' "$OUT/prepare.log" | tail -n 1

# Guest configuration: sempose config, parameters, command frames (from the DBC).
cp "$CONFIG" "$OUT/guest-cfg/system.yaml"
cat > "$OUT/guest-cfg/params.env" <<P
DURATION=$DURATION
SEMPOSE_ARGS="$ARGS"
P
if [ -f "$DBC" ]; then
  if ! $PY "$HERE/make_commands.py" "$DBC" "$DURATION" > "$OUT/guest-cfg/commands.txt" 2> "$OUT/make_commands.log"; then
    : > "$OUT/guest-cfg/commands.txt"
  fi
  cat "$OUT/make_commands.log"
else
  log "no DBC at $DBC: no command frames will be injected"
  : > "$OUT/guest-cfg/commands.txt"
fi
cp "$OUT/guest-cfg/commands.txt" "$OUT/artifacts/commands_planned.txt"

SEMPOSE_IN=""
if [ -x "$SEMPOSE" ]; then SEMPOSE_IN=$SEMPOSE; else log "WARNING: sempose binary '$SEMPOSE' missing"; fi
if ! "$HERE/build_initramfs.sh" "$CACHE/current.env" "$OUT/initramfs.img" "$OUT/guest-cfg" "$SEMPOSE_IN" 2>&1; then
  echo "FAIL: initramfs build failed"; exit 1
fi
. "$CACHE/current.env"

# Boot: retry only when the guest never reached /init (a TCG boot hang), never on a
# guest-reported failure.
BOOT_STALL_S=${SEMPOSE_SYSTEM_BOOT_STALL:-25}   # no console progress before /init
BOOT_MAX_S=${SEMPOSE_SYSTEM_BOOT_MAX:-90}       # /init not reached at all
VM_MAX_S=$(( 150 + 3 * DURATION ))              # whole guest run
status=""; ATT=""
for attempt in $(seq 1 "$BOOTS"); do
  ATT="$OUT/attempt-$attempt"; mkdir -p "$ATT"
  log "boot attempt $attempt/$BOOTS (kernel $KVER, TCG)"
  timeout "$VM_MAX_S" "$QEMU" -accel tcg -machine pc -smp 2 -m 512 -cpu max \
    -kernel "$VMLINUX" -initrd "$OUT/initramfs.img" \
    -append "console=ttyS0 panic=-1 tsc=reliable" \
    -display none -nodefaults -no-reboot -nic none \
    -serial "file:$ATT/console.log" -serial "file:$ATT/results.raw" \
    -device isa-debug-exit,iobase=0xf4,iosize=0x04 > "$ATT/qemu.log" 2>&1 &
  QPID=$!
  last_size=-1; last_change=$(date +%s); start=$(date +%s); stalled=""
  while kill -0 $QPID 2>/dev/null; do
    sleep 0.5
    grep -q "^STAGE init" "$ATT/results.raw" 2>/dev/null && continue
    size=$(stat -c %s "$ATT/console.log" 2>/dev/null || echo 0)
    now=$(date +%s)
    if [ "$size" != "$last_size" ]; then last_size=$size; last_change=$now; fi
    if [ $((now - last_change)) -ge "$BOOT_STALL_S" ] || [ $((now - start)) -ge "$BOOT_MAX_S" ]; then
      stalled="no console progress for $((now - last_change)) s before /init"
      kill $QPID 2>/dev/null; break
    fi
  done
  wait $QPID; status=$?
  tr -d '\r' < "$ATT/results.raw" > "$ATT/results.txt"
  log "qemu exit status $status after $(( $(date +%s) - start )) s${stalled:+ ($stalled)}"
  if grep -q "^STAGE init" "$ATT/results.txt"; then break; fi
  log "guest never reached /init; console tail:"; tail -n 5 "$ATT/console.log" | tr -d '\r' | sed 's/^/    /'
done

cp "$ATT/console.log" "$OUT/artifacts/console.log" 2>/dev/null
cp "$ATT/results.txt" "$OUT/artifacts/results.txt" 2>/dev/null
# Unpack the artifact tarball (base64 between marker lines).
sed -n '/^=== ARTIFACTS BEGIN/,/^=== ARTIFACTS END/p' "$OUT/artifacts/results.txt" | sed '1d;$d' |
  base64 -d 2>/dev/null | tar xzf - --no-overwrite-dir -C "$OUT/artifacts" 2>/dev/null ||
  log "could not unpack the guest artifacts"

fail_tail() {
  echo "---- guest console tail ($ATT/console.log) ----"
  tail -n 40 "$ATT/console.log" 2>/dev/null | tr -d '\r'
  echo "---- guest results ----"
  grep -v '^[A-Za-z0-9+/=]*$' "$ATT/results.txt" 2>/dev/null | grep -v '^$' | tail -n 40
  echo "---- artifacts: $OUT/artifacts ----"
}
case "$status" in
  1|3) ;;   # isa-debug-exit: guest verdict pass / fail
  124) log "guest timed out after $VM_MAX_S s" ;;
  *)   log "qemu ended without a verdict (status $status: panic or power-off?)" ;;
esac
if ! grep -q "^VERDICT" "$OUT/artifacts/results.txt" 2>/dev/null; then
  fail_tail; echo "FAIL: no verdict from the guest (qemu status $status)"; exit 1
fi

log "host checks"
$PY "$HERE/check_results.py" --artifacts "$OUT/artifacts" --dbc "$DBC" --duration "$DURATION" \
    --report "$OUT/report.txt"
rc=$?
log "done in $(( $(date +%s) - T0 )) s; artifacts in $OUT/artifacts, report $OUT/report.txt"
if [ $rc -ne 0 ] || [ "$status" != 1 ]; then
  fail_tail; echo "FAIL: system test (qemu status $status, checker rc $rc)"; exit 1
fi
echo "PASS: system test"
exit 0
