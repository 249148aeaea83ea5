# Sourced by run_system_test.sh and run_systemd_test.sh: the one QEMU set-up both VMs use.
QEMU=$(command -v qemu-system-x86_64 || true)
# require_qemu: exit 77 (CTest skip) when qemu cannot start at all here.
require_qemu() {
  if [ -z "$QEMU" ] || ! echo quit | timeout 30 "$QEMU" -machine none -accel tcg -display none \
         -nodefaults -monitor stdio >/dev/null 2>&1; then
    echo "SKIP: qemu-system-x86_64 cannot start here (apt-get install qemu-system-x86)"; exit 77
  fi
}
# start_vm MAX_S MEM_MB INITRD APPEND DIR: boots $VMLINUX (TCG, 2 vCPUs, no network) in the
# background, killed after MAX_S; console on DIR/console.log, the guest's result channel
# (ttyS1) on DIR/results.raw, qemu's own output in DIR/qemu.log; the guest ends it through
# isa-debug-exit (qemu exit status 1 = pass, 3 = fail). Sets QPID.
start_vm() {
  timeout "$1" "$QEMU" -accel tcg -machine pc -smp 2 -m "$2" -cpu max \
    -kernel "$VMLINUX" -initrd "$3" -append "$4" \
    -display none -nodefaults -no-reboot -nic none \
    -serial "file:$5/console.log" -serial "file:$5/results.raw" \
    -device isa-debug-exit,iobase=0xf4,iosize=0x04 > "$5/qemu.log" 2>&1 &
  QPID=$!
}
