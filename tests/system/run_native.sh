#!/bin/bash
# run_native.sh SEMPOSE_BINARY CAN_GPIO_HW_TEST_BINARY OUT_DIR
# The system test's checks on this machine instead of the VM: a real PREEMPT_RT box with a
# CAN interface (or vcan) and gpio-sim. Runs guest/guest_test.sh natively (as root) and then
# check_results.py on its artifacts. Exit 0 pass, 1 fail, 77 skip (no vcan/CAN or gpio-sim).
# Env: SYSTEST_CAN (default vcan0; created with `ip link add ... type vcan` when absent; a
#      real interface such as can0 must be up, at a bitrate, with another node or
#      `loopback on` so frames are acknowledged), SEMPOSE_SYSTEM_DURATION (5),
#      SEMPOSE_SYSTEM_CONFIG (system.yaml), SYSTEST_ALLOW_NON_RT=1 to accept a non-RT kernel,
#      SEMPOSE_COMEDI_HW_TEST (the comedi_hw_test binary: with comedi_test and sem_emul loaded
#      (tests/system/guest/init shows how) the Comedi steps run too, else they are skipped).
# Needs: root, can-utils (candump, cansend), gpiod (gpioinfo/gpioget/gpioset/gpiomon),
#        rt-tests (cyclictest), util-linux (chrt), modules can-raw, vcan and gpio-sim
#        (CONFIG_GPIO_SIM; Debian's RT kernel lacks it: prepare_host.sh builds it out of tree).
set -uo pipefail
SEMPOSE=$(readlink -f "${1:?usage: run_native.sh SEMPOSE CAN_GPIO_HW_TEST OUT_DIR}")
HWTEST=$(readlink -f "${2:?usage: run_native.sh SEMPOSE CAN_GPIO_HW_TEST OUT_DIR}")
OUT=${3:?usage: run_native.sh SEMPOSE CAN_GPIO_HW_TEST OUT_DIR}
HERE=$(cd "$(dirname "$0")" && pwd)
DURATION=${SEMPOSE_SYSTEM_DURATION:-5}
CONFIG=${SEMPOSE_SYSTEM_CONFIG:-$HERE/system.yaml}
CAN=${SYSTEST_CAN:-vcan0}

[ "$(id -u)" = 0 ] || { echo "SKIP: run_native.sh needs root (CAN interfaces, gpio-sim configfs, SCHED_FIFO)"; exit 77; }
for t in candump cansend gpioinfo gpioget gpioset gpiomon cyclictest chrt ip; do
  command -v $t > /dev/null || { echo "FAIL: '$t' not installed (can-utils gpiod rt-tests util-linux iproute2)"; exit 1; }
done
modprobe -q can-raw 2>/dev/null; modprobe -q vcan 2>/dev/null; modprobe -q gpio-sim 2>/dev/null
grep -q " /sys/kernel/config " /proc/mounts || mount -t configfs configfs /sys/kernel/config 2>/dev/null
if [ ! -d /sys/kernel/config/gpio-sim ]; then
  echo "SKIP: no gpio-sim (modprobe gpio-sim failed; CONFIG_GPIO_SIM not set in $(uname -r))"; exit 77
fi
if ! ip link show "$CAN" > /dev/null 2>&1 && ! { case $CAN in vcan*) true ;; *) false ;; esac && [ -d /sys/module/vcan ]; }; then
  echo "SKIP: no CAN interface $CAN and no vcan module"; exit 77
fi

mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)
rm -rf "$OUT/cfg" "$OUT/artifacts" "$OUT/report.txt"
mkdir -p "$OUT/artifacts"
"$HERE/prepare_config.sh" "$SEMPOSE" "$CONFIG" "$OUT/cfg" "$DURATION" || { echo "FAIL: config preflight"; exit 1; }
BIN=$(mktemp -d); trap 'rm -rf "$BIN"' EXIT
ln -s "$SEMPOSE" "$BIN/sempose"; ln -s "$HWTEST" "$BIN/can_gpio_hw_test"
# Comedi (optional natively: checked only when comedi_test and sem_emul are loaded).
[ -n "${SEMPOSE_COMEDI_HW_TEST:-}" ] && ln -s "$(readlink -f "$SEMPOSE_COMEDI_HW_TEST")" "$BIN/comedi_hw_test"
: > "$OUT/artifacts/results.txt"
PATH="$BIN:$PATH" SYSTEST_NATIVE=1 SYSTEST_TAR=0 SYSTEST_CFG="$OUT/cfg" SYSTEST_OUT="$OUT/artifacts" \
  SYSTEST_RESULTS="$OUT/artifacts/results.txt" SYSTEST_CAN="$CAN" bash "$HERE/guest/guest_test.sh"
grc=$?
/usr/bin/python3 "$HERE/check_results.py" --artifacts "$OUT/artifacts" --duration "$DURATION" --report "$OUT/report.txt"
rc=$?
if [ $rc -ne 0 ] || [ $grc -ne 0 ]; then
  grep -E '^(CHECK .* FAIL|VERDICT)' "$OUT/artifacts/results.txt"
  tail -n 15 "$OUT/artifacts/sempose_stderr.txt" 2>/dev/null
  echo "FAIL: native system test (target side rc $grc, checker rc $rc); artifacts in $OUT/artifacts"; exit 1
fi
echo "PASS: native system test on $(uname -r), $CAN; artifacts in $OUT/artifacts"
