#!/bin/sh
# Guest side of the sempose system test (busybox ash, run by /init).
# Protocol on /dev/ttyS1 (host: results.txt), one record per line:
#   STAGE <name> ...            progress
#   CHECK <name> PASS|FAIL|SKIP <detail>
#   INFO ...
#   === ARTIFACTS BEGIN / base64 of a tar.gz of /out / === ARTIFACTS END
#   VERDICT PASS|FAIL <failed checks>
# Exit status 0 when every guest-side CHECK passed (sempose ones included).
export PATH=/usr/bin:/usr/sbin:/bin:/sbin
R=/dev/ttyS1
FAILED=""
DURATION=5
SYNC_HALF_PERIOD_S=0.003     # pull-up / pull-down half period -> ~150 Hz frame sync
SYNC_LINE=0; VALID_LINE=1; HEARTBEAT_LINE=2
SELF_IN=7; SELF_OUT=6; SELF_MON=5
SEMPOSE_ARGS=""
[ -f /cfg/params.env ] && . /cfg/params.env

say()   { echo "$*" > $R; echo "[guest] $*"; }
check() { # check NAME PASS|FAIL|SKIP detail...
  n=$1; st=$2; shift 2
  say "CHECK $n $st $*"
  [ "$st" = FAIL ] && FAILED="$FAILED $n"
  return 0
}
# Fork-free sleep (fork is expensive under TCG): read with a timeout on an idle fifo.
mkfifo /tmp/nap.fifo; exec 7<>/tmp/nap.fifo
nap() { read -t "$1" _nap <&7; }
now_ms() { awk '{printf "%d\n", $1*1000}' /proc/uptime; }
# wait_for TIMEOUT_MS COMMAND...: poll (10 ms) until COMMAND succeeds.
wait_for() {
  t_end=$(( $(now_ms) + $1 )); shift
  while ! "$@" >/dev/null 2>&1; do
    [ "$(now_ms)" -ge "$t_end" ] && return 1
    nap 0.01
  done
  return 0
}
can_rx_count() { cat /proc/net/can/rcvlist_* 2>/dev/null | grep vcan0 | grep -vc "no entry" ; }
can_rx_more_than() { [ "$(can_rx_count)" -gt "$1" ]; }
line_requested() { gpioinfo "$CHIP" 2>/dev/null | grep -E "line +$1:" | grep -q '\[used'; }
file_has() { grep -q "$2" "$1"; }

say "STAGE guest realtime=$(cat /sys/kernel/realtime 2>/dev/null || echo 0) cpus=$(grep -c ^processor /proc/cpuinfo)"
[ "$(cat /sys/kernel/realtime 2>/dev/null)" = 1 ] && check preempt_rt PASS "/sys/kernel/realtime=1" \
  || check preempt_rt FAIL "/sys/kernel/realtime missing or 0"
lsmod > /out/lsmod.txt 2>/dev/null
cat /proc/modules | awk '{print $1}' | tr '\n' ' ' | sed 's/^/INFO modules: /' > $R; echo > $R

# ---- vcan0 ---------------------------------------------------------------------------
if ip link add dev vcan0 type vcan && ip link set vcan0 up; then
  check vcan PASS "$(ip -o link show vcan0 | head -c 120)"
else
  check vcan FAIL "cannot create vcan0"
fi

# ---- gpio-sim chip (configfs) ----------------------------------------------------------
G=/sys/kernel/config/gpio-sim/chip0
CHIP=""; SIM=""
if mkdir -p $G/bank0 && echo 8 > $G/bank0/num_lines && echo 1 > $G/live; then
  CHIP=$(cat $G/bank0/chip_name); DEV=$(cat $G/dev_name)
  SIM=/sys/devices/platform/$DEV/$CHIP
  [ -d "$SIM" ] && check gpio_sim PASS "chip=$CHIP dev=$DEV" || check gpio_sim FAIL "no $SIM"
else
  check gpio_sim FAIL "gpio-sim configfs setup failed"
fi
echo "$CHIP" > /out/gpio_chip.txt
pull() { echo "pull-$2" > "$SIM/sim_gpio$1/pull"; }

# ---- self-check: CAN loop through candump ----------------------------------------------
base=$(can_rx_count)
candump -L vcan0 > /tmp/selfcheck_candump.log 2>&1 &
SC_PID=$!
if wait_for 10000 can_rx_more_than "$base"; then
  cansend vcan0 7FF#DEADBEEF
  if wait_for 5000 file_has /tmp/selfcheck_candump.log "vcan0 7FF#DEADBEEF"; then
    check can_selfcheck PASS "cansend 7FF#DEADBEEF seen by candump"
  else
    check can_selfcheck FAIL "frame not seen: $(head -c 200 /tmp/selfcheck_candump.log)"
  fi
else
  check can_selfcheck FAIL "candump never bound its socket"
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
  gpiomon --num-events=1 --rising-edge "$CHIP" $SELF_MON > /tmp/gpiomon.txt 2>&1 &
  GM=$!
  if wait_for 5000 line_requested $SELF_MON; then
    pull $SELF_MON up
    if wait_for 5000 file_has /tmp/gpiomon.txt RISING; then
      check gpio_edge PASS "$(cat /tmp/gpiomon.txt)"
    else
      check gpio_edge FAIL "no rising edge event"
    fi
  else
    check gpio_edge FAIL "gpiomon never requested line $SELF_MON"
  fi
  kill $GM 2>/dev/null; wait $GM 2>/dev/null
fi

# ---- cyclictest baseline (same duration, idle system) ----------------------------------
say "STAGE cyclictest ${DURATION}s"
cyclictest -q -m -t1 -p80 -i1000 -D "$DURATION" -h 1000 > /out/cyclictest_hist.txt 2>/out/cyclictest_stderr.txt
rc=$?
grep -q "Max Latencies" /out/cyclictest_hist.txt && check cyclictest PASS "$(grep -E '^# (Min|Avg|Max) Lat' /out/cyclictest_hist.txt | tr -s ' ' | tr '\n' ' ')" \
  || check cyclictest FAIL "rc=$rc $(head -c 200 /out/cyclictest_stderr.txt)"

# ---- sempose ---------------------------------------------------------------------------
run_sempose() {
  if [ ! -x /usr/bin/sempose ]; then
    check sempose_present FAIL "no sempose binary in the initramfs"; return
  fi
  sed -e "s/@GPIO_CHIP@/$CHIP/g" -e "s/@DURATION@/$DURATION/g" /cfg/system.yaml > /out/system.yaml
  # Main reference client: candump on vcan0 for the whole sempose run.
  base=$(can_rx_count)
  candump -L vcan0 > /out/candump.log 2>/out/candump_stderr.txt &
  CD=$!
  wait_for 10000 can_rx_more_than "$base" || check candump_bound FAIL "candump never bound"
  base=$(can_rx_count)
  # Frame sync: rising edges on SYNC_LINE driven through gpio-sim's pull attribute.
  pull $SYNC_LINE down
  ( n=0; while [ ! -f /tmp/stop_sync ]; do
      pull $SYNC_LINE up; nap $SYNC_HALF_PERIOD_S
      pull $SYNC_LINE down; nap $SYNC_HALF_PERIOD_S
      n=$((n+1))
    done; echo $n > /tmp/sync_edges ) &
  SYNC=$!
  # Output sampler: record every change of the pose-valid / heartbeat outputs.
  ( pv=x; ph=x
    while [ ! -f /tmp/stop_sample ]; do
      read v < $SIM/sim_gpio$VALID_LINE/value; read h < $SIM/sim_gpio$HEARTBEAT_LINE/value
      if [ "$v" != "$pv" ] || [ "$h" != "$ph" ]; then read up _ < /proc/uptime; echo "$up valid=$v heartbeat=$h"; pv=$v; ph=$h; fi
      nap 0.002
    done ) > /out/gpio_outputs.txt &
  SAMP=$!
  say "STAGE sempose run --duration $DURATION"
  # shellcheck disable=SC2086
  sempose run --config /out/system.yaml --duration "$DURATION" --hist-dir /out \
      $SEMPOSE_ARGS > /out/sempose_stdout.txt 2> /out/sempose_stderr.txt &
  SP=$!
  # Commands only once sempose's CAN socket is bound and its frame-sync line requested.
  # (stop waiting as soon as sempose has exited)
  bound_or_gone() { ! kill -0 $SP 2>/dev/null || can_rx_more_than "$base"; }
  requested_or_gone() { ! kill -0 $SP 2>/dev/null || line_requested $SYNC_LINE; }
  wait_for 15000 bound_or_gone
  if can_rx_more_than "$base"; then
    check sempose_can_bound PASS "sempose CAN socket bound on vcan0"
  else
    check sempose_can_bound FAIL "sempose bound no CAN socket on vcan0 within 15 s$(kill -0 $SP 2>/dev/null || echo ' (sempose exited)')"
  fi
  wait_for 5000 requested_or_gone
  line_requested $SYNC_LINE && check sempose_gpio_requested PASS "line $SYNC_LINE requested" \
    || check sempose_gpio_requested FAIL "frame-sync line $SYNC_LINE not requested: $(gpioinfo "$CHIP" 2>&1 | sed -n 2,4p | tr -s ' \n' ' ')"
  if [ -s /cfg/commands.txt ] && kill -0 $SP 2>/dev/null; then
    # commands.txt: "<delay_ms> <label> <id>#<data>" (delay before sending)
    while read -r d label frame; do
      case "$d" in ''|\#*) continue ;; esac
      nap "$(awk "BEGIN{print $d/1000}")"
      if cansend vcan0 "$frame"; then echo "$(now_ms) $label $frame" >> /out/commands_sent.txt
      else echo "$(now_ms) $label $frame SEND-FAILED" >> /out/commands_sent.txt; fi
    done < /cfg/commands.txt
  fi
  wait $SP; SRC=$?
  echo $SRC > /out/sempose_exit_code.txt
  touch /tmp/stop_sync /tmp/stop_sample; wait $SYNC $SAMP 2>/dev/null
  echo "$(cat /tmp/sync_edges 2>/dev/null) rising edges" > /out/sync_edges.txt
  nap 0.2   # let candump drain what sempose sent last (socket already closed)
  kill $CD 2>/dev/null; wait $CD 2>/dev/null
  if grep -q "not built yet" /out/sempose_stderr.txt /out/sempose_stdout.txt; then
    check sempose_built FAIL "sempose answers: $(grep -h 'not built yet' /out/sempose_stderr.txt /out/sempose_stdout.txt | head -1)"
  elif [ $SRC -ne 0 ]; then
    check sempose_exit FAIL "exit code $SRC: $(tail -c 300 /out/sempose_stderr.txt | tr '\n' ' ')"
  else
    check sempose_exit PASS "$(tail -n 1 /out/sempose_stdout.txt | head -c 400)"
  fi
}
if [ -n "$SIM" ]; then run_sempose; else check sempose_exit FAIL "no gpio-sim chip, sempose not run"; fi

# ---- artifacts ------------------------------------------------------------------------
dmesg > /out/dmesg.txt 2>&1
cat /proc/interrupts > /out/interrupts.txt 2>/dev/null
say "=== ARTIFACTS BEGIN"
tar czf - -C /out . | base64 > $R
say "=== ARTIFACTS END"
if [ -z "$FAILED" ]; then say "VERDICT PASS"; exit 0; fi
say "VERDICT FAIL$FAILED"; exit 1
