#!/bin/bash
# run_systemd_test.sh BUILD_DIR OUT_DIR
# The Debian package under a real systemd: CPack builds the package from BUILD_DIR, Debian 12's
# PREEMPT_RT kernel boots in QEMU (TCG) with systemd as PID 1 (this machine's systemd
# package), the package laid out as dpkg installs it, and the unit is driven and judged from
# inside (guest_systemd/check.sh): started through Type=notify, user from sysusers.d,
# capabilities, SCHED_FIFO threads, sandbox, watchdog fed, SIGUSR1 histograms, a SIGSTOP'ed
# process killed by the watchdog and restarted, a clean stop with exit 0.
# Exit 0 pass, 1 fail, 77 skip (no qemu / no systemd package / no cpack).
set -uo pipefail
BUILD=${1:?usage: run_systemd_test.sh BUILD_DIR OUT_DIR}
OUT=${2:?usage: run_systemd_test.sh BUILD_DIR OUT_DIR}
HERE=$(cd "$(dirname "$0")" && pwd)
CACHE=${SEMPOSE_SYSTEM_CACHE:-/var/cache/sempose-system-test}
VM_MAX_S=${SEMPOSE_SYSTEMD_VM_MAX:-420}
T0=$(date +%s)
log() { echo "[systemd-test +$(( $(date +%s) - T0 ))s] $*"; }

. "$HERE/vm_common.sh"
require_qemu
command -v cpack >/dev/null && command -v dpkg-deb >/dev/null || { echo "SKIP: cpack or dpkg-deb missing"; exit 77; }
dpkg-query -W -f='${Status}' systemd 2>/dev/null | grep -q "ok installed" ||
  { echo "SKIP: the systemd package is not installed (ci/setup installs it)"; exit 77; }

mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)
rm -rf "$OUT"/pkg "$OUT"/console.log "$OUT"/results.* "$OUT"/report.txt
log "prepare host cache $CACHE"
if ! "$HERE/prepare_host.sh" "$CACHE" > "$OUT/prepare.log" 2>&1; then
  tail -n 30 "$OUT/prepare.log"; echo "FAIL: host preparation failed (see $OUT/prepare.log)"; exit 1
fi
. "$CACHE/current.env"
# Its own package folder (-B; CPack also copies the package to BUILD_DIR/packages, which is why
# this test and package_install share a CTest RESOURCE_LOCK).
if ! (cd "$BUILD" && cpack -G DEB -B "$OUT/pkg" > "$OUT/cpack.log" 2>&1); then
  tail -n 20 "$OUT/cpack.log"; echo "FAIL: cpack"; exit 1
fi
DEB=$(find "$OUT/pkg" -name "sempose_*.deb" | head -n1)
[ -n "$DEB" ] || { echo "FAIL: no package in $OUT/pkg"; exit 1; }
if ! "$HERE/build_systemd_initramfs.sh" "$CACHE/current.env" "$OUT/initramfs-systemd.img" "$DEB"; then
  echo "FAIL: initramfs build failed"; exit 1
fi
log "boot: kernel $KVER, systemd as PID 1, TCG, 2 vCPUs"
start_vm "$VM_MAX_S" 1024 "$OUT/initramfs-systemd.img" \
  "console=ttyS0 panic=-1 tsc=reliable noirqdebug systemd.show_status=1" "$OUT"
# Ends by itself (isa-debug-exit); stopped on a kernel panic or after VM_MAX_S.
stage=""; why=""
while kill -0 $QPID 2>/dev/null; do
  sleep 1
  s=$(grep -a '^STAGE\|^CHECK' "$OUT/results.raw" 2>/dev/null | tail -n 1 | tr -d '\r')
  if [ -n "$s" ] && [ "$s" != "$stage" ]; then stage=$s; log "guest: ${s:0:150}"; fi
  if grep -aq 'Kernel panic' "$OUT/console.log" 2>/dev/null; then why="kernel panic"; sleep 2; kill $QPID; break; fi
  if [ $(( $(date +%s) - T0 )) -ge "$VM_MAX_S" ]; then why="timed out after $VM_MAX_S s"; kill $QPID; break; fi
done
wait $QPID
status=$?
tr -d '\r' < "$OUT/results.raw" > "$OUT/results.txt" 2>/dev/null
log "qemu exit status $status${why:+ ($why)}"
grep -E '^(STAGE|CHECK|VERDICT)' "$OUT/results.txt" | tee "$OUT/report.txt"
if grep -q '^VERDICT PASS' "$OUT/results.txt" && [ "$status" = 1 ]; then
  echo "PASS: the package's unit under systemd (report: $OUT/report.txt, console: $OUT/console.log)"; exit 0
fi
echo "---- console tail ($OUT/console.log) ----"; tail -n 40 "$OUT/console.log" | tr -d '\r'
echo "FAIL: the package's unit under systemd (see $OUT/report.txt)"; exit 1
