#!/bin/bash
# run_system_test.sh SEMPOSE_BINARY OUT_DIR [CAN_GPIO_HW_TEST_BINARY [COMEDI_HW_TEST_BINARY]]
# The sempose system test (issue 7): boots Debian's PREEMPT_RT kernel in QEMU (TCG), brings
# up vcan0 + a gpio-sim chip, runs can_gpio_hw_test, candump, cyclictest and `sempose run`
# inside (guest/guest_test.sh), copies the artifacts out over a second serial port and checks
# them on the host (check_results.py). Exit: 0 pass, 1 fail, 77 skip (only when qemu cannot
# start at all).
# Env: SEMPOSE_SYSTEM_CACHE (default /var/cache/sempose-system-test), SEMPOSE_SYSTEM_DURATION
#      (s, default 5), SEMPOSE_SYSTEM_CONFIG (default tests/system/system.yaml),
#      SEMPOSE_DBC (default ipc/sempose.dbc), SEMPOSE_SYSTEM_BOOTS (attempts, default 3).
set -uo pipefail
SEMPOSE=${1:?usage: run_system_test.sh SEMPOSE_BINARY OUT_DIR [CAN_GPIO_HW_TEST]}
OUT=${2:?usage: run_system_test.sh SEMPOSE_BINARY OUT_DIR [CAN_GPIO_HW_TEST]}
HWTEST=${3:-}
COMEDI_HWTEST=${4:-}
HERE=$(cd "$(dirname "$0")" && pwd)
SRC=$(cd "$HERE/../.." && pwd)
CACHE=${SEMPOSE_SYSTEM_CACHE:-/var/cache/sempose-system-test}
DURATION=${SEMPOSE_SYSTEM_DURATION:-5}
CONFIG=${SEMPOSE_SYSTEM_CONFIG:-$HERE/system.yaml}
DBC=${SEMPOSE_DBC:-$SRC/ipc/sempose.dbc}
BOOTS=${SEMPOSE_SYSTEM_BOOTS:-3}
PY=/usr/bin/python3
T0=$(date +%s.%N)
el() { awk -v a="$T0" -v b="$(date +%s.%N)" 'BEGIN{printf "%.1f", b-a}'; }
log() { echo "[system-test +$(el)s] $*"; }

. "$HERE/vm_common.sh"
require_qemu
[ -x "$SEMPOSE" ] || { echo "FAIL: sempose binary '$SEMPOSE' missing (build the sempose target)"; exit 1; }
if [ -z "$HWTEST" ] || [ ! -x "$HWTEST" ]; then
  echo "FAIL: can_gpio_hw_test binary '${HWTEST}' missing (build the can_gpio_hw_test target)"; exit 1
fi
if [ -z "$COMEDI_HWTEST" ] || [ ! -x "$COMEDI_HWTEST" ]; then
  echo "FAIL: comedi_hw_test binary '${COMEDI_HWTEST}' missing (build the comedi_hw_test target)"; exit 1
fi

mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)
rm -rf "$OUT"/attempt-* "$OUT/artifacts" "$OUT/guest-cfg" "$OUT/report.txt"
mkdir -p "$OUT/guest-cfg" "$OUT/artifacts"

log "prepare host cache $CACHE"
if ! "$HERE/prepare_host.sh" "$CACHE" > "$OUT/prepare.log" 2>&1; then
  tail -n 30 "$OUT/prepare.log"; echo "FAIL: host preparation failed (see $OUT/prepare.log)"; exit 1
fi
grep '^\[prepare\]' "$OUT/prepare.log" | tail -n 1

# Guest configuration (system.yaml, the recorded pattern, params) + host preflight of the config.
if ! "$HERE/prepare_config.sh" "$SEMPOSE" "$CONFIG" "$OUT/guest-cfg" "$DURATION"; then
  echo "FAIL: the system-test config does not run on the host (see above)"; exit 1
fi
if ! "$HERE/build_initramfs.sh" "$CACHE/current.env" "$OUT/initramfs.img" "$OUT/guest-cfg" "$SEMPOSE" "$HWTEST" "$COMEDI_HWTEST" 2>&1; then
  echo "FAIL: initramfs build failed"; exit 1
fi
. "$CACHE/current.env"
log "host ready"

# Boot. A retry only when the VM produced no verdict (a TCG boot hang, a panic, a timeout);
# a guest that reports failure is never retried.
BOOT_STALL_S=${SEMPOSE_SYSTEM_BOOT_STALL:-25}   # no console progress before /init
BOOT_MAX_S=${SEMPOSE_SYSTEM_BOOT_MAX:-90}       # /init not reached at all
XFER_STALL_S=${SEMPOSE_SYSTEM_XFER_STALL:-30}   # artifact upload stopped growing
VM_MAX_S=$(( 240 + 4 * DURATION ))              # whole guest run (incl. the Comedi steps)
status=""; ATT=""
for attempt in $(seq 1 "$BOOTS"); do
  ATT="$OUT/attempt-$attempt"; mkdir -p "$ATT"
  log "boot attempt $attempt/$BOOTS (kernel $KVER, TCG, 2 vCPUs)"
  # noirqdebug: under PREEMPT_RT the 8250's IRQ is threaded, and on TCG the THRE interrupt is
  # often already gone when the thread looks, so the long artifact upload on ttyS1 piles up
  # "unhandled" counts until the kernel disables IRQ 3 ("nobody cared") and the upload stops.
  start_vm "$VM_MAX_S" 512 "$OUT/initramfs.img" "console=ttyS0 panic=-1 tsc=reliable noirqdebug" "$ATT"
  last_size=-1; last_change=$(date +%s); start=$(date +%s); stalled=""; stage=""
  xfer_size=-1; xfer_change=$start
  while kill -0 $QPID 2>/dev/null; do
    sleep 0.5
    # progress: the guest's STAGE lines
    s=$(grep -a '^STAGE' "$ATT/results.raw" 2>/dev/null | tail -n 1 | tr -d '\r')
    if [ -n "$s" ] && [ "$s" != "$stage" ]; then stage=$s; log "guest: $s"; fi
    if [ -n "$stage" ]; then
      # The artifact upload is a steady stream; a stop means the guest's UART went quiet
      # (see noirqdebug above), and waiting out VM_MAX_S would only delay the retry.
      grep -aq '^=== ARTIFACTS BEGIN' "$ATT/results.raw" 2>/dev/null || continue
      size=$(stat -c %s "$ATT/results.raw" 2>/dev/null || echo 0); now=$(date +%s)
      if [ "$size" != "$xfer_size" ]; then xfer_size=$size; xfer_change=$now; fi
      if [ $((now - xfer_change)) -ge "$XFER_STALL_S" ]; then
        stalled="artifact upload stopped at $size bytes for $((now - xfer_change)) s"
        kill $QPID 2>/dev/null; break
      fi
      continue
    fi
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
  if grep -q "^VERDICT" "$ATT/results.txt"; then break; fi
  log "no verdict from attempt $attempt; console tail:"; tail -n 8 "$ATT/console.log" | tr -d '\r' | sed 's/^/    /'
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
  echo "---- guest checks and stages ----"
  grep -E '^(STAGE|CHECK|INFO|VERDICT)' "$ATT/results.txt" 2>/dev/null | tail -n 40
  if [ -s "$OUT/artifacts/sempose_stderr.txt" ]; then
    echo "---- sempose stderr (tail) ----"; tail -n 15 "$OUT/artifacts/sempose_stderr.txt"
  fi
  if [ -s "$OUT/artifacts/sempose_stdout.txt" ]; then
    echo "---- sempose stdout (tail) ----"; tail -n 15 "$OUT/artifacts/sempose_stdout.txt"
  fi
  echo "---- artifacts: $OUT/artifacts ----"
}
case "$status" in
  1|3) ;;   # isa-debug-exit: guest verdict pass / fail
  124) log "guest timed out after $VM_MAX_S s" ;;
  *)   log "qemu ended without a verdict (status $status: panic or power-off?)" ;;
esac
if ! grep -q "^VERDICT" "$OUT/artifacts/results.txt" 2>/dev/null; then
  fail_tail; echo "FAIL: no verdict from the guest after $BOOTS attempt(s) (qemu status $status)"; exit 1
fi

log "host checks"
$PY "$HERE/check_results.py" --artifacts "$OUT/artifacts" --dbc "$DBC" --duration "$DURATION" \
    --report "$OUT/report.txt"
rc=$?
log "done in $(el) s (boot attempts: $attempt); artifacts in $OUT/artifacts, report $OUT/report.txt"
if [ $rc -ne 0 ] || [ "$status" != 1 ]; then
  fail_tail
  echo "FAILED CHECKS: $(grep -E '^FAIL' "$OUT/report.txt" 2>/dev/null | awk '{print $2}' | tr '\n' ' ')$(grep -E '^VERDICT FAIL' "$OUT/artifacts/results.txt" | cut -d' ' -f3-)"
  echo "FAIL: system test (qemu status $status, checker rc $rc)"; exit 1
fi
echo "PASS: system test"
exit 0
