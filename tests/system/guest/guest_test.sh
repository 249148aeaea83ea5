#!/bin/sh
# The sempose system test's target side: run by /init inside the PREEMPT_RT VM (busybox ash),
# or natively by tests/system/run_native.sh (bash, as root, on a box with vcan/CAN + gpio-sim).
#
# Records, one per line, to $R (VM: /dev/ttyS1 -> host results.txt; native: a file):
#   STAGE <name> ...            progress
#   CHECK <name> PASS|FAIL <detail>
#   INFO ...
#   === ARTIFACTS BEGIN / base64 of a tar.gz of $OUT / === ARTIFACTS END   (VM only)
#   VERDICT PASS|FAIL <failed checks>
# Exit status 0 when every target-side CHECK passed; the host checks the artifacts afterwards
# (check_results.py). No fixed sleeps before sending: every step waits for the event it needs
# (a bound CAN socket, a requested GPIO line, a heartbeat that acknowledges a command).
#
# Environment (defaults are the VM's):
#   SYSTEST_CFG  (/cfg)  system.yaml, pattern_*.pgm, params.env     SYSTEST_OUT (/out) artifacts
#   SYSTEST_RESULTS (/dev/ttyS1)    SYSTEST_CAN (vcan0; created when it is a vcan name and absent)
#   SYSTEST_TAR (1: send $OUT as base64 on $R)   SYSTEST_ALLOW_NON_RT (0: a non-PREEMPT_RT kernel fails)
#   SEMPOSE_BIN (sempose), SEMPOSE_HW_TEST (can_gpio_hw_test), SEMPOSE_COMEDI_HW_TEST (comedi_hw_test)
#   SYSTEST_COMEDI_TEST / SYSTEST_COMEDI_SEM: the comedi_test / sem_emul device (found in sysfs
#   when unset); natively, Comedi checks skip when neither exists, in the VM they fail.
export PATH=/usr/bin:/usr/sbin:/bin:/sbin:$PATH
CFG=${SYSTEST_CFG:-/cfg}
OUT=${SYSTEST_OUT:-/out}
R=${SYSTEST_RESULTS:-/dev/ttyS1}
CAN=${SYSTEST_CAN:-vcan0}
SEMPOSE=${SEMPOSE_BIN:-sempose}
HWTEST=${SEMPOSE_HW_TEST:-can_gpio_hw_test}
COMEDI_HWTEST=${SEMPOSE_COMEDI_HW_TEST:-comedi_hw_test}
COMEDI_RUN_S=6               # sempose run with source: comedi (the emulated SEM)
TMP=$OUT/.tmp
FAILED=""
DURATION=5
SYNC_HALF_PERIOD_S=0.008     # frame-sync pull-up/pull-down half period (~50 Hz under TCG)
POLL_S=0.02                  # wait_for period
SYNC_LINE=0; VALID_LINE=1; HEARTBEAT_LINE=2     # sempose's lines (system.yaml)
HW_LINES=3,4,5                                  # can_gpio_hw_test's lines (in, valid, heartbeat)
SELF_IN=7; SELF_OUT=6; SELF_MON=5
ACK_TIMEOUT_MS=15000         # a command's acknowledgement in the heartbeat
MAX_RUN_S=150                # sempose's --duration: a cap; it is stopped with SIGTERM
# Command frames (protocol.hpp / sempose.dbc, base id 0x100 -> COMMAND 0x150).
CMD_SELECT=150#0101010000000000      # SELECT_PATTERN_SET seq 1 arg 1 (keep the configured scale)
CMD_REACQUIRE=150#0402FF0000000000   # REACQUIRE seq 2, all targets
CMD_MALFORMED=150#09030000           # 4 bytes: bad length -> counted, ignored
[ -f "$CFG/params.env" ] && . "$CFG/params.env"
mkdir -p "$OUT" "$TMP"

say()   { echo "$*" >> "$R"; echo "[target] $*"; }
check() { # check NAME PASS|FAIL|SKIP detail...
  n=$1; st=$2; shift 2
  say "CHECK $n $st $*"
  [ "$st" = FAIL ] && FAILED="$FAILED $n"
  return 0
}
# Fork-free sleep (fork is expensive under TCG): read with a timeout on an idle fifo.
rm -f "$TMP/nap.fifo"; mkfifo "$TMP/nap.fifo"; exec 7<>"$TMP/nap.fifo"
nap() { read -t "$1" _nap <&7; }
now_ms() { # fork-free: /proc/uptime has two decimals
  read up _ < /proc/uptime; ms="${up%.*}${up#*.}0"
  while [ "${ms#0}" != "$ms" ] && [ "${#ms}" -gt 1 ]; do ms=${ms#0}; done   # no octal
  echo "$ms"
}
# wait_for TIMEOUT_MS COMMAND...: poll (20 ms) until COMMAND succeeds.
wait_for() {
  t_end=$(( $(now_ms) + $1 )); shift
  while ! "$@" >/dev/null 2>&1; do
    [ "$(now_ms)" -ge "$t_end" ] && return 1
    nap $POLL_S
  done
  return 0
}
# CAN_RAW sockets on the interface: candump (no filter) is in rcvlist_all, sempose (one
# command id, error frames) in rcvlist_sff / rcvlist_err.
can_rx_count() { cat /proc/net/can/rcvlist_* 2>/dev/null | grep -c " $CAN " ; }
can_rx_more_than() { [ "$(can_rx_count)" -gt "$1" ]; }
line_requested() { gpioinfo "$CHIP" 2>/dev/null | grep -E "line +$1:" | grep -q '\[used'; }
file_has() { grep -qE "$2" "$1"; }
alive() { kill -0 "$1" 2>/dev/null; }

cleanup() {  # native runs: leave the machine as found
  [ -n "$CD" ] && kill "$CD" 2>/dev/null
  [ -n "$SYNC" ] && touch "$TMP/stop_sync"
  [ -n "$SAMP" ] && touch "$TMP/stop_sample"
  if [ "${SYSTEST_NATIVE:-0}" = 1 ]; then
    [ -n "$G" ] && [ -d "$G" ] && { echo 0 > "$G/live"; rmdir "$G/bank0" "$G"; } 2>/dev/null
    [ "$CREATED_CAN" = 1 ] && ip link del "$CAN" 2>/dev/null
  fi
}
trap cleanup EXIT

rt=$(cat /sys/kernel/realtime 2>/dev/null || echo 0)
say "STAGE target kernel=$(uname -r) realtime=$rt cpus=$(grep -c ^processor /proc/cpuinfo)"
if [ "$rt" = 1 ]; then check preempt_rt PASS "/sys/kernel/realtime=1 ($(uname -r))"
elif [ "${SYSTEST_ALLOW_NON_RT:-0}" = 1 ]; then check preempt_rt SKIP "not a PREEMPT_RT kernel (SYSTEST_ALLOW_NON_RT=1)"
else check preempt_rt FAIL "/sys/kernel/realtime missing or 0: not a PREEMPT_RT kernel ($(uname -r))"; fi
cut -d' ' -f1 /proc/modules | tr '\n' ' ' > "$OUT/modules.txt"

# ---- CAN interface ---------------------------------------------------------------------
CREATED_CAN=0
if ip link show "$CAN" >/dev/null 2>&1; then
  check can_if PASS "using existing $CAN: $(ip -o link show "$CAN" | head -c 120)"
elif case $CAN in vcan*) true ;; *) false ;; esac &&
     ip link add dev "$CAN" type vcan && ip link set "$CAN" mtu 72 && ip link set "$CAN" up; then
  # MTU 72: CAN FD capable, so can_gpio_hw_test's FD case runs too (sempose uses fd: off).
  CREATED_CAN=1
  check can_if PASS "created $CAN: $(ip -o link show "$CAN" | head -c 120)"
else
  check can_if FAIL "no interface $CAN and cannot create it"
fi

# ---- gpio-sim chip (configfs) ----------------------------------------------------------
G=/sys/kernel/config/gpio-sim/sempose-systest
CHIP=""; SIM=""
if mkdir -p $G/bank0 && echo 8 > $G/bank0/num_lines && echo 1 > $G/live; then
  CHIP=$(cat $G/bank0/chip_name); DEV=$(cat $G/dev_name)
  SIM=/sys/devices/platform/$DEV/$CHIP
  [ -d "$SIM" ] && check gpio_sim PASS "chip=$CHIP dev=$DEV" || check gpio_sim FAIL "no $SIM"
else
  check gpio_sim FAIL "gpio-sim configfs setup failed (module gpio-sim loaded? configfs mounted?)"
fi
echo "$CHIP" > "$OUT/gpio_chip.txt"
pull() { echo "pull-$2" > "$SIM/sim_gpio$1/pull"; }

# ---- self-check: CAN loop through candump ----------------------------------------------
base=$(can_rx_count)
candump -L "$CAN" > "$TMP/selfcheck_candump.log" 2>&1 &
SC_PID=$!
if wait_for 10000 can_rx_more_than "$base"; then
  cansend "$CAN" 7FF#DEADBEEF
  if wait_for 5000 file_has "$TMP/selfcheck_candump.log" "$CAN 7FF#DEADBEEF"; then
    check can_selfcheck PASS "cansend 7FF#DEADBEEF seen by candump"
  else
    check can_selfcheck FAIL "frame not seen: $(head -c 200 "$TMP/selfcheck_candump.log")"
  fi
else
  check can_selfcheck FAIL "candump never bound its socket (/proc/net/can/rcvlist_all)"
fi
kill $SC_PID 2>/dev/null; wait $SC_PID 2>/dev/null

# ---- self-check: gpio-sim input, output and edge events --------------------------------
if [ -n "$SIM" ]; then
  pull $SELF_IN up;   a=$(gpioget "$CHIP" $SELF_IN)
  pull $SELF_IN down; b=$(gpioget "$CHIP" $SELF_IN)
  [ "$a$b" = 10 ] && check gpio_input PASS "pull-up->$a pull-down->$b" \
    || check gpio_input FAIL "pull-up->$a pull-down->$b"
  gpioset --mode=signal "$CHIP" $SELF_OUT=1 &
  GS=$!
  if wait_for 5000 line_requested $SELF_OUT; then
    v=$(cat $SIM/sim_gpio$SELF_OUT/value)
    [ "$v" = 1 ] && check gpio_output PASS "gpioset 1 -> sim value $v" || check gpio_output FAIL "sim value $v"
  else
    check gpio_output FAIL "gpioset never requested line $SELF_OUT"
  fi
  kill $GS 2>/dev/null; wait $GS 2>/dev/null
  pull $SELF_MON down
  gpiomon --num-events=1 --rising-edge "$CHIP" $SELF_MON > "$TMP/gpiomon.txt" 2>&1 &
  GM=$!
  if wait_for 5000 line_requested $SELF_MON; then
    # gpiomon exits after its one event (and only then flushes its stdout to the file).
    # The line shows as requested a moment before its edge interrupt is set up (gpiolib requests
    # the line, then the IRQ): under slow TCG beside other tests an edge in that moment was lost
    # (a FAIL once in a local ctest -j2). So the edge is driven again, up to 5 times 3 s apart.
    gone() { ! alive $GM; }
    for _ in 1 2 3 4 5; do
      pull $SELF_MON up
      wait_for 3000 gone && break
      pull $SELF_MON down
    done
    if grep -q RISING "$TMP/gpiomon.txt"; then
      check gpio_edge PASS "$(cat "$TMP/gpiomon.txt")"
    else
      check gpio_edge FAIL "no rising edge event from 5 edges 3 s apart: $(head -c 200 "$TMP/gpiomon.txt")"
    fi
  else
    check gpio_edge FAIL "gpiomon never requested line $SELF_MON"
  fi
  kill $GM 2>/dev/null; wait $GM 2>/dev/null
fi

# ---- can_gpio_hw_test: sempose's SocketCAN and libgpiod code against the real drivers ----
if [ -n "$SIM" ]; then
  say "STAGE can_gpio_hw_test"
  if command -v "$HWTEST" >/dev/null 2>&1; then
    SEMPOSE_CAN=$CAN SEMPOSE_GPIO_CHIP=$CHIP SEMPOSE_GPIO_LINES=$HW_LINES "$HWTEST" --gtest_brief=1 \
      > "$OUT/can_gpio_hw_test.txt" 2>&1
    rc=$?
    summary=$(grep -E '^\[ *(PASSED|FAILED|SKIPPED) *\]' "$OUT/can_gpio_hw_test.txt" | tr -s ' ' | tr '\n' ' ')
    if grep -q '^\[  SKIPPED \]' "$OUT/can_gpio_hw_test.txt"; then
      check can_gpio_hw_test FAIL "skips where the interfaces exist (rc $rc): $summary"
    elif [ $rc -ne 0 ]; then
      check can_gpio_hw_test FAIL "rc $rc: $summary $(grep -m3 -E 'Failure|FAILED' "$OUT/can_gpio_hw_test.txt" | tr '\n' ' ' | head -c 300)"
    else
      check can_gpio_hw_test PASS "$summary"
    fi
  else
    check can_gpio_hw_test FAIL "$HWTEST not found"
  fi
fi

# ---- Comedi: the real driver path (comedi_test) and the emulated SEM (sem_emul) ---------
# Which /dev/comediN is which: the class device's parent is the driver's own device.
comedi_dev_of() { # NAME -> /dev/comediN whose hardware device is NAME
  for d in /sys/class/comedi/comedi[0-9]*; do
    [ -e "$d/device" ] || continue
    [ "$(basename "$(readlink -f "$d/device")")" = "$1" ] && { echo "/dev/${d##*/}"; return 0; }
  done
  return 1
}
COMEDI_TEST=${SYSTEST_COMEDI_TEST:-$(comedi_dev_of comedi_testd)}   # comedi_test's device name
COMEDI_SEM=${SYSTEST_COMEDI_SEM:-$(comedi_dev_of sem_emul)}
COMEDI_SKIP=""
if [ -z "$COMEDI_TEST" ] || [ -z "$COMEDI_SEM" ]; then
  if [ "${SYSTEST_NATIVE:-0}" = 1 ]; then
    COMEDI_SKIP="no comedi_test/sem_emul device on this box"; check comedi_devices SKIP "$COMEDI_SKIP"
  else check comedi_devices FAIL "comedi_test='$COMEDI_TEST' sem_emul='$COMEDI_SEM': $(ls /dev/comedi* 2>&1 | tr '\n' ' ')"; fi
else
  check comedi_devices PASS "comedi_test on $COMEDI_TEST, sem_emul on $COMEDI_SEM"
fi
# comedi_test and sem_emul pace their samples with kernel timers, which on PREEMPT_RT run in
# the ktimers/N threads (SCHED_FIFO 1): raised above sempose's stages (60/50/40) they are
# never starved by them (a real card's IRQ thread needs the same, see the README).
set_ktimers() { # PRIORITY: only around the Comedi steps, so the other steps run as before
  for c in /proc/[0-9]*/comm; do
    read -r comm < "$c" 2>/dev/null || continue
    case "$comm" in ktimers/*) p=${c%/comm}; p=${p#/proc/}
      chrt -f -p "$1" "$p" > /dev/null && echo "$p $comm -> SCHED_FIFO $1" >> "$OUT/ktimers_priorities.txt" ;;
    esac
  done
}
raise_ktimers() { set_ktimers 80; }
restore_ktimers() { set_ktimers 1; }   # PREEMPT_RT's default
if [ -n "$COMEDI_SKIP" ]; then
  check comedi_hw_test SKIP "$COMEDI_SKIP"
elif [ -n "$COMEDI_TEST" ] && [ -n "$COMEDI_SEM" ]; then
  say "STAGE comedi_hw_test"
  raise_ktimers
  if command -v "$COMEDI_HWTEST" >/dev/null 2>&1; then
    SEMPOSE_COMEDI_TEST_DEVICE=$COMEDI_TEST SEMPOSE_COMEDI_SEM_DEVICE=$COMEDI_SEM \
      SEMPOSE_COMEDI_SEM_SCENE=$CFG/sem_scene.pgm "$COMEDI_HWTEST" --gtest_brief=0 > "$OUT/comedi_hw_test.txt" 2>&1
    rc=$?
    summary=$(grep -E '^\[ *(PASSED|FAILED|SKIPPED) *\]' "$OUT/comedi_hw_test.txt" | tr -s ' ' | tr '\n' ' ')
    if grep -q '^\[  SKIPPED \]' "$OUT/comedi_hw_test.txt"; then
      check comedi_hw_test FAIL "skips where the devices exist (rc $rc): $summary"
    elif [ $rc -ne 0 ]; then
      check comedi_hw_test FAIL "rc $rc: $summary $(grep -m3 -E 'Failure|FAILED|error' "$OUT/comedi_hw_test.txt" | tr '\n' ' ' | head -c 300)"
    else
      check comedi_hw_test PASS "$summary"
    fi
  else
    check comedi_hw_test FAIL "$COMEDI_HWTEST not found"
  fi
  restore_ktimers
fi

# ---- cyclictest baseline (same duration, idle system) ----------------------------------
say "STAGE cyclictest ${DURATION}s"
cyclictest -q -m -t1 -p80 -i1000 -D "$DURATION" -h 2000 > "$OUT/cyclictest_hist.txt" 2>"$OUT/cyclictest_stderr.txt"
rc=$?
grep -q "Max Latencies" "$OUT/cyclictest_hist.txt" && check cyclictest PASS "$(grep -E '^# (Min|Avg|Max) Lat' "$OUT/cyclictest_hist.txt" | tr -s ' ' | tr '\n' ' ')" \
  || check cyclictest FAIL "rc=$rc $(head -c 200 "$OUT/cyclictest_stderr.txt")"

# ---- sempose run -----------------------------------------------------------------------
# heartbeat (0x140) as candump -L prints it: byte 1 = bad_commands<<4 | pattern_set,
# byte 3 = last_command_seq.
HB_SELECT_ACK=' 140#[0-9A-F]{3}1[0-9A-F]{2}01'      # pattern_set 1, last_command_seq 1
HB_REACQ_ACK=' 140#[0-9A-F]{6}02'                   # last_command_seq 2
HB_BAD_COUNTED=' 140#[0-9A-F]{2}1'                  # bad_commands 1
send_and_await() { # LABEL FRAME REGEX: send when sempose runs, wait for the heartbeat's answer
  alive $SP || { check "cmd_$1" FAIL "sempose exited before the command"; return; }
  t0=$(now_ms)
  if cansend "$CAN" "$2"; then echo "$t0 $1 $2" >> "$OUT/commands_sent.txt"
  else echo "$t0 $1 $2 SEND-FAILED" >> "$OUT/commands_sent.txt"; check "cmd_$1" FAIL "cansend failed"; return; fi
  acked() { ! alive $SP || grep -qE "$1" "$OUT/candump.log"; }
  wait_for $ACK_TIMEOUT_MS acked "$3"
  if grep -qE "$3" "$OUT/candump.log"; then
    check "cmd_$1" PASS "$2 answered in the heartbeat after $(( $(now_ms) - t0 )) ms"
  else
    check "cmd_$1" FAIL "$2: no heartbeat matching '$3' within $ACK_TIMEOUT_MS ms$(alive $SP || echo ' (sempose exited)')"
  fi
}
run_sempose() {
  if ! command -v "$SEMPOSE" >/dev/null 2>&1; then
    check sempose_exit FAIL "no sempose binary ($SEMPOSE)"; return
  fi
  sed -e "s|@GPIO_CHIP@|$CHIP|g" -e "s|@CAN_IF@|$CAN|g" -e "s|@OUT@|$OUT|g" \
      "$CFG/system.yaml" > "$CFG/system.run.yaml"   # next to the pattern files it names
  cp "$CFG/system.run.yaml" "$OUT/system.yaml"
  # check-rt on the RT kernel with the real vcan and gpio-sim: kernel, limits, CAN link and the
  # three GPIO lines must pass (isolation, throttling and IRQs are the VM's and may warn).
  "$SEMPOSE" check-rt --config "$CFG/system.run.yaml" > "$OUT/check_rt.txt" 2>&1; crc=$?
  notpass=""
  for n in kernel memlock rtprio can gpio.frame_sync_line gpio.pose_valid_line gpio.heartbeat_line; do
    grep -q "^PASS  $n " "$OUT/check_rt.txt" || notpass="$notpass $n"
  done
  if [ -z "$notpass" ]; then check check_rt PASS "rc $crc; $(tail -n1 "$OUT/check_rt.txt")"
  else check check_rt FAIL "not passing:$notpass; $(grep -E '^(WARN|FAIL)' "$OUT/check_rt.txt" | head -c 300 | tr '\n' ';')"; fi
  rm -f "$TMP/stop_sync" "$TMP/stop_sample" "$OUT/commands_sent.txt"
  # The reference client: candump on the bus for the whole run.
  base=$(can_rx_count)
  candump -L "$CAN" > "$OUT/candump.log" 2>"$OUT/candump_stderr.txt" &
  CD=$!
  wait_for 10000 can_rx_more_than "$base" || check candump_bound FAIL "candump never bound its socket"
  base=$(can_rx_count)
  # Frame sync: rising edges on SYNC_LINE through gpio-sim's pull attribute (real edge IRQs).
  pull $SYNC_LINE down
  ( n=0; while [ ! -f "$TMP/stop_sync" ]; do
      pull $SYNC_LINE up; nap $SYNC_HALF_PERIOD_S
      pull $SYNC_LINE down; nap $SYNC_HALF_PERIOD_S
      n=$((n+1))
    done; echo $n > "$TMP/sync_edges" ) &
  SYNC=$!
  # The scan generator is hardware: it must not starve behind sempose's SCHED_FIFO threads.
  chrt -f -p 70 $SYNC > /dev/null || check sync_priority FAIL "chrt -f -p 70 failed"
  # Output sampler: every change of the pose-valid / heartbeat outputs (gpio-sim's value).
  ( pv=x; ph=x
    while [ ! -f "$TMP/stop_sample" ]; do
      read v < $SIM/sim_gpio$VALID_LINE/value; read h < $SIM/sim_gpio$HEARTBEAT_LINE/value
      if [ "$v" != "$pv" ] || [ "$h" != "$ph" ]; then read up _ < /proc/uptime; echo "$up valid=$v heartbeat=$h"; pv=$v; ph=$h; fi
      nap 0.003
    done ) > "$OUT/gpio_outputs.txt" &
  SAMP=$!
  chrt -f -p 70 $SAMP > /dev/null || check sampler_priority FAIL "chrt -f -p 70 failed"
  say "STAGE sempose run (>= ${DURATION}s, SIGTERM after the commands)"
  # Runs until SIGTERM once the commands were answered and it ran >= DURATION s (how long
  # its setup and the commands take under TCG varies); --duration is only a safety cap.
  T_START=$(now_ms)
  "$SEMPOSE" run --config "$CFG/system.run.yaml" --duration "$MAX_RUN_S" --hist-dir "$OUT" \
      > "$OUT/sempose_stdout.txt" 2> "$OUT/sempose_stderr.txt" &
  SP=$!
  bound_or_gone() { ! alive $SP || can_rx_more_than "$base"; }
  requested_or_gone() { ! alive $SP || line_requested $SYNC_LINE; }
  posing_or_gone() { ! alive $SP || file_has "$OUT/candump.log" ' 101#'; }
  tracking_or_gone() { ! alive $SP || { read v < $SIM/sim_gpio$VALID_LINE/value && [ "$v" = 1 ]; }; }
  wait_for 60000 bound_or_gone
  if can_rx_more_than "$base"; then check sempose_can_bound PASS "sempose's CAN socket bound on $CAN"
  else check sempose_can_bound FAIL "sempose bound no CAN socket on $CAN$(alive $SP || echo ' (sempose exited)')"; fi
  wait_for 10000 requested_or_gone
  if line_requested $SYNC_LINE; then
    check sempose_gpio_requested PASS "$(gpioinfo "$CHIP" | grep -E 'line +[0-2]:' | tr -s ' \t' ' ' | tr '\n' ';')"
  else
    check sempose_gpio_requested FAIL "frame-sync line $SYNC_LINE not requested$(alive $SP || echo ' (sempose exited)')"
  fi
  # PREEMPT_RT tuning a real deployment needs too: the frame-sync edge reaches sempose via
  # the irq_work kthreads (FIFO 1 by default) and the line's threaded IRQ handler
  # "irq/NN-sempose" (FIFO 50); both must outrank the acquisition thread (FIFO 60) that
  # waits for the edge, or the edge waits behind it.
  for c in /proc/[0-9]*/comm; do
    read -r comm < "$c" 2>/dev/null || continue
    case "$comm" in irq_work/*|irq/*-sempose) p=${c%/comm}; p=${p#/proc/}
      chrt -f -p 80 "$p" > /dev/null && echo "$p $comm -> SCHED_FIFO 80" >> "$OUT/irq_priorities.txt" ;;
    esac
  done
  grep -q -- '-sempose' "$OUT/irq_priorities.txt" 2>/dev/null ||
    check frame_sync_irq_priority FAIL "no irq/NN-sempose thread found to raise: $(cat "$OUT/irq_priorities.txt" 2>/dev/null | tr '\n' ';')"
  # The controller side (this script, cansend, grep) runs on its own box in reality: do not
  # let RT throttling behind sempose's threads starve it. Its children inherit this.
  chrt -f -p 70 $$ > /dev/null
  POLL_S=0.05
  wait_for 60000 posing_or_gone
  # sempose's own duration_s counts from its first scan, not from its launch (setup under
  # TCG takes seconds): measure "at least DURATION s" from the first pose too.
  T_START=$(now_ms)
  if alive $SP; then
    # The kernel's view of sempose's threads (policy, priority, CPU) and locked memory.
    for t in /proc/$SP/task/*; do echo "$(cat $t/stat)"; done > "$OUT/sempose_threads.txt" 2>/dev/null
    grep -E '^(VmLck|VmRSS|Cpus_allowed_list)' /proc/$SP/status > "$OUT/sempose_status.txt" 2>/dev/null
    send_and_await select "$CMD_SELECT" "$HB_SELECT_ACK"
    # REACQUIRE is to take a target that is being tracked: a pose with reason 32 follows (the
    # ROI frame in flight ACQUIRING, or the search's pose UNCERTAIN), pose-valid drops and comes
    # back. Sent while the start search still runs (every scan full-field; under TCG that can
    # last seconds), pose-valid would never have been high before it: one rise only.
    if ! wait_for 60000 tracking_or_gone; then
      say "note: no TRACKING pose (pose-valid low) within 60 s of the select; REACQUIRE sent anyway"
    fi
    send_and_await reacquire "$CMD_REACQUIRE" "$HB_REACQ_ACK"
    send_and_await malformed "$CMD_MALFORMED" "$HB_BAD_COUNTED"
  else
    check sempose_posing FAIL "sempose exited before its first pose"
  fi
  # A few seconds of tracking after the last command, and at least DURATION s in all.
  t_min=$(( T_START + DURATION * 1000 )); t_tail=$(( $(now_ms) + 1500 ))
  [ $t_tail -gt $t_min ] && t_min=$t_tail
  long_enough() { ! alive $SP || [ "$(now_ms)" -ge $t_min ]; }
  wait_for 120000 long_enough
  chrt -o -p 0 $$ > /dev/null; POLL_S=0.02
  alive $SP && kill -TERM $SP
  wait $SP; SRC=$?
  echo $SRC > "$OUT/sempose_exit_code.txt"
  touch "$TMP/stop_sync" "$TMP/stop_sample"; wait $SYNC $SAMP 2>/dev/null
  echo "$(cat "$TMP/sync_edges" 2>/dev/null) rising edges" > "$OUT/sync_edges.txt"
  # candump has everything sempose sent once the heartbeat after exit would have come; it
  # writes each frame as it receives it, so stopping it now loses nothing already sent.
  nap 0.2
  kill $CD 2>/dev/null; wait $CD 2>/dev/null; CD=""; SYNC=""; SAMP=""
  if [ "$SRC" -ne 0 ]; then
    check sempose_exit FAIL "exit code $SRC: $(tail -c 300 "$OUT/sempose_stderr.txt" | tr '\n' ' ')"
  else
    check sempose_exit PASS "$(tail -n 1 "$OUT/sempose_stdout.txt" | head -c 400)"
  fi
}
if [ -n "$SIM" ]; then run_sempose; else check sempose_exit FAIL "no gpio-sim chip, sempose not run"; fi

# ---- sempose run while its CAN interface is unplugged and plugged in again ---------------
# A USB-CAN adapter pulled out and put back is an interface deleted and created again (a new
# ifindex). sempose must say so, count what it cannot send, bind again once the interface is
# back and send poses on it, in one run: a candump on the re-created interface sees them.
RB_IF=semposerb1
rx_on() { cat /proc/net/can/rcvlist_* 2>/dev/null | grep -c " $1 " ; }
rx_on_more_than() { [ "$(rx_on "$1")" -gt "$2" ]; }
run_sempose_rebind() {
  B=$OUT/rebind; mkdir -p "$B"
  ip link del "$RB_IF" 2>/dev/null
  if ! { ip link add dev "$RB_IF" type vcan && ip link set "$RB_IF" up; }; then
    check can_rebind FAIL "cannot create $RB_IF"; return
  fi
  # The main run's config without GPIO (its lines belong to that run), CAN on $RB_IF.
  sed -e '/^gpio:/d' -e "s|@CAN_IF@|$RB_IF|g" -e "s|@OUT@|$B|g" "$CFG/system.yaml" > "$CFG/rebind.run.yaml"
  base=$(rx_on $RB_IF)
  candump -L "$RB_IF" > "$B/candump_before.log" 2>/dev/null &
  CD=$!
  wait_for 10000 rx_on_more_than $RB_IF "$base" || { check can_rebind FAIL "candump never bound on $RB_IF"; return; }
  say "STAGE sempose run with $RB_IF deleted and created again"
  "$SEMPOSE" run --config "$CFG/rebind.run.yaml" --duration "$MAX_RUN_S" > "$B/sempose_stdout.txt" 2> "$B/sempose_stderr.txt" &
  SP=$!
  chrt -f -p 70 $$ > /dev/null; POLL_S=0.05
  on_bus_or_gone() { ! alive $SP || file_has "$B/candump_before.log" ' 101#'; }
  said_or_gone() { ! alive $SP || file_has "$B/sempose_stdout.txt" "$1"; }
  detail=""
  wait_for 60000 on_bus_or_gone
  if ! file_has "$B/candump_before.log" ' 101#'; then detail="no pose on $RB_IF before the unplug"
  else
    ip link del "$RB_IF"; wait $CD 2>/dev/null; CD=""    # candump ends with its interface
    wait_for 15000 said_or_gone "fault: CAN interface $RB_IF is gone" ||
      detail="no 'fault: CAN interface $RB_IF is gone' line"
    ip link add dev "$RB_IF" type vcan && ip link set "$RB_IF" up
    base=$(rx_on $RB_IF)
    candump -L "$RB_IF" > "$B/candump_after.log" 2>/dev/null &
    CD=$!
    wait_for 10000 rx_on_more_than $RB_IF "$base"
    wait_for 15000 said_or_gone "fault cleared: CAN interface $RB_IF is back" ||
      detail="$detail; no 'fault cleared' line"
    back_or_gone() { ! alive $SP || file_has "$B/candump_after.log" ' 101#'; }
    wait_for 15000 back_or_gone
    file_has "$B/candump_after.log" ' 101#' || detail="$detail; no pose on the re-created $RB_IF"
  fi
  chrt -o -p 0 $$ > /dev/null; POLL_S=0.02
  alive $SP && kill -TERM $SP
  wait $SP; rc=$?
  nap 0.2
  [ -n "$CD" ] && { kill $CD 2>/dev/null; wait $CD 2>/dev/null; CD=""; }
  ip link del "$RB_IF" 2>/dev/null
  rm -f "$B"/latency_hist*.txt "$B"/*.json   # histograms: the main run's are checked; keep the transfer short
  summ=$(grep '^summary:' "$B/sempose_stdout.txt")
  [ $rc -eq 0 ] || detail="$detail; exit code $rc: $(tail -c 200 "$B/sempose_stderr.txt" | tr '\n' ' ')"
  echo "$summ" | grep -q ' can_rebinds=1' || detail="$detail; summary without can_rebinds=1"
  if [ -z "$detail" ]; then
    check can_rebind PASS "$(grep -c ' 101#' "$B/candump_after.log") poses on the re-created $RB_IF; $(grep -o 'can_sent=[0-9]* can_dropped=[0-9]*' "$B/sempose_stdout.txt" | tail -n1) can_rebinds=1"
  else
    check can_rebind FAIL "${detail#; }"
  fi
}
if [ -n "$SIM" ]; then run_sempose_rebind; else check can_rebind FAIL "no gpio-sim chip, sempose not run"; fi

# ---- sempose run on the emulated SEM through Comedi (source: comedi) ----------------------
# The scene's target is static at a known pose (sem_scene_truth.csv); poses go to vcan0 and
# are read back by candump; the host compares them with the truth (check_results.py).
run_sempose_comedi() {
  C=$OUT/comedi; mkdir -p "$C"
  cp "$CFG/sem_scene_truth.csv" "$CFG/sim_reference.txt" "$C/" 2>/dev/null
  sed -e "s|@COMEDI_SEM@|$COMEDI_SEM|g" -e "s|@CAN_IF@|$CAN|g" -e "s|@OUT@|$C|g" \
      "$CFG/system_comedi.yaml" > "$CFG/system_comedi.run.yaml"
  cp "$CFG/system_comedi.run.yaml" "$C/system_comedi.yaml"
  base=$(can_rx_count)
  candump -L "$CAN" > "$C/candump.log" 2>"$C/candump_stderr.txt" &
  CD=$!
  wait_for 10000 can_rx_more_than "$base" || check comedi_candump_bound FAIL "candump never bound its socket"
  raise_ktimers
  say "STAGE sempose run source=comedi ${COMEDI_RUN_S}s on $COMEDI_SEM"
  "$SEMPOSE" run --config "$CFG/system_comedi.run.yaml" --duration "$COMEDI_RUN_S" --hist-dir "$C" \
      > "$C/sempose_stdout.txt" 2> "$C/sempose_stderr.txt"
  rc=$?
  nap 0.2
  kill $CD 2>/dev/null; wait $CD 2>/dev/null; CD=""
  restore_ktimers
  # The host reads the JSON; the cyclictest-layout text (~600 KB) would only lengthen the
  # artifact transfer over the emulated serial port.
  rm -f "$C/latency_hist.txt"
  if [ $rc -ne 0 ]; then
    check comedi_run FAIL "exit code $rc: $(tail -c 300 "$C/sempose_stderr.txt" | tr '\n' ' ')"
  else
    check comedi_run PASS "$(tail -n 1 "$C/sempose_stdout.txt" | head -c 400)"
  fi
}
if [ -n "$COMEDI_SKIP" ]; then check comedi_run SKIP "$COMEDI_SKIP"
elif [ -n "$COMEDI_SEM" ]; then run_sempose_comedi
else check comedi_run FAIL "no sem_emul device"; fi

# ---- artifacts ------------------------------------------------------------------------
dmesg > "$OUT/dmesg.txt" 2>&1
cat /proc/interrupts > "$OUT/interrupts.txt" 2>/dev/null
rm -rf "$TMP"
if [ "${SYSTEST_TAR:-1}" = 1 ]; then
  say "=== ARTIFACTS BEGIN"
  tar czf - -C "$OUT" . | base64 >> "$R"
  say "=== ARTIFACTS END"
fi
if [ -z "$FAILED" ]; then say "VERDICT PASS"; exit 0; fi
say "VERDICT FAIL$FAILED"; exit 1
