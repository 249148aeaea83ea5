#!/bin/sh
# The systemd-boot VM's check (sempose-systest.service, after sempose.service is up): drives
# the packaged unit through a real systemd as PID 1 and records, one per line, to /dev/ttyS1:
#   CHECK <name> PASS|FAIL <detail>   ...   VERDICT PASS|FAIL <failed checks>
# then powers the VM off through isa-debug-exit (qemu's exit status 1 pass, 3 fail).
R=/dev/ttyS1
stty -F $R raw -echo 2>/dev/null
FAILED=""
say() { echo "$*" > $R; echo "[check] $*"; }
check() { n=$1; st=$2; shift 2; say "CHECK $n $st $*"; [ "$st" = FAIL ] && FAILED="$FAILED $n"; return 0; }
prop() { systemctl show sempose -p "$1" --value 2>/dev/null; }
wait_for() { # SECONDS COMMAND...: poll every 0.5 s
  t=$(( $1 * 2 )); shift
  while ! "$@" >/dev/null 2>&1; do t=$((t - 1)); [ $t -le 0 ] && return 1; sleep 0.5; done
}
active() { [ "$(systemctl is-active sempose)" = active ]; }
say "STAGE systemd $(systemctl --version | head -n1) as PID 1: $(cat /proc/1/comm)"
[ "$(cat /proc/1/comm)" = systemd ] && check systemd_pid1 PASS "$(systemctl --version | head -n1)" ||
  check systemd_pid1 FAIL "PID 1 is $(cat /proc/1/comm)"

# 1. Started by systemd through the package's unit: sysusers made the user, Type=notify
#    readiness (READY=1 after setup) made it active.
if active; then check service_active PASS "sempose.service active ($(prop SubState)) after READY=1, MainPID $(prop MainPID)"
else check service_active FAIL "$(systemctl status sempose --no-pager 2>&1 | tail -n 12 | tr '\n' ';')"; fi
grep -q '^sempose:' /etc/passwd && check sysusers PASS "$(grep '^sempose:' /etc/passwd)" ||
  check sysusers FAIL "no sempose user in /etc/passwd (the package's sysusers.d file)"
PID=$(prop MainPID)
if [ -n "$PID" ] && [ "$PID" != 0 ] && [ -d /proc/$PID ]; then
  uid=$(awk '/^Uid:/{print $2}' /proc/$PID/status); suid=$(awk -F: '/^sempose:/{print $3}' /etc/passwd)
  capeff=$(awk '/^CapEff:/{print $2}' /proc/$PID/status); capbnd=$(awk '/^CapBnd:/{print $2}' /proc/$PID/status)
  nnp=$(awk '/^NoNewPrivs:/{print $2}' /proc/$PID/status); sec=$(awk '/^Seccomp:/{print $2}' /proc/$PID/status)
  # CAP_IPC_LOCK (14) and CAP_SYS_NICE (23): 0x804000, nothing else.
  if [ "$uid" = "$suid" ] && [ "$capeff" = 0000000000804000 ] && [ "$capbnd" = 0000000000804000 ] && [ "$nnp" = 1 ] && [ "$sec" = 2 ]; then
    check identity PASS "uid $uid (sempose), CapEff=CapBnd=$capeff (ipc_lock, sys_nice), NoNewPrivs 1, seccomp filter"
  else
    check identity FAIL "uid $uid (sempose $suid) CapEff $capeff CapBnd $capbnd NoNewPrivs $nnp Seccomp $sec"
  fi
  # The RT stages: SCHED_FIFO (policy 1) at the configured priorities, granted by the two
  # capabilities and LimitRTPRIO alone.
  fifo=""
  for t in /proc/$PID/task/*; do
    set -- $(sed 's/^.*) //' $t/stat)   # fields after comm: $1 = field 3
    pol=$(eval echo \${39}); rtp=$(eval echo \${38})
    [ "$pol" = 1 ] && fifo="$fifo $(cat $t/comm):$rtp"
  done
  case "$fifo" in *:60*) ;; *) fifo="";; esac
  [ -n "$fifo" ] && check rt_threads PASS "SCHED_FIFO threads:$fifo" || check rt_threads FAIL "no SCHED_FIFO 60 thread under the unit"
  # The sandbox as the process sees it: / read-only (ProtectSystem=strict), its logs folder writable.
  root_opts=$(awk '$5 == "/" {print $6}' /proc/$PID/mountinfo | head -n1)
  logs_opts=$(awk '$5 == "/var/log/sempose" {print $6}' /proc/$PID/mountinfo | head -n1)
  case "$root_opts,$logs_opts" in ro*,rw*) check sandbox PASS "/ $root_opts, /var/log/sempose $logs_opts in its mount namespace" ;;
    *) check sandbox FAIL "/ '$root_opts', /var/log/sempose '$logs_opts'" ;; esac
else
  for n in identity rt_threads sandbox; do check $n FAIL "no main process"; done
fi

# 2. The watchdog is fed: still active, no restart, well past WatchdogSec (5 s).
w0=$(prop WatchdogTimestampMonotonic)
sleep 12
w1=$(prop WatchdogTimestampMonotonic)
if active && [ "$(prop NRestarts)" = 0 ] && [ -n "$w1" ] && [ "$w1" != 0 ] && [ "$w1" != "$w0" ]; then
  check watchdog_fed PASS "12 s later: active, NRestarts 0, last WATCHDOG=1 at ${w1} us (was ${w0})"
else
  check watchdog_fed FAIL "active=$(systemctl is-active sempose) NRestarts=$(prop NRestarts) WatchdogTimestamp $w0 -> $w1"
fi

# 3. Histograms on demand, as the unit's comment says: systemctl kill -s USR1.
rm -f /var/log/sempose/latency_hist.json
systemctl kill -s USR1 sempose
hist() { [ -s /var/log/sempose/latency_hist.json ]; }
if wait_for 20 hist; then check histograms_usr1 PASS "$(ls -l /var/log/sempose/latency_hist.json | awk '{print $1, $3, $5}')"
else check histograms_usr1 FAIL "no /var/log/sempose/latency_hist.json 20 s after SIGUSR1"; fi

# 4. A stalled process starves the watchdog: SIGSTOP it; systemd must kill it (watchdog
#    timeout) and restart it (Restart=on-failure), a new main process active again.
old=$(prop MainPID)
kill -STOP "$old"
restarted() { [ "$(prop NRestarts)" -ge 1 ] && active && [ "$(prop MainPID)" != "$old" ]; }
timed_out() { journalctl -u sempose --no-pager -o cat 2>/dev/null | grep -m1 'Watchdog timeout'; }
if wait_for 150 restarted && [ -n "$(timed_out)" ]; then
  check watchdog_restart PASS "SIGSTOP'ed $old: '$(timed_out)', restarted as $(prop MainPID) (NRestarts $(prop NRestarts))"
else
  check watchdog_restart FAIL "NRestarts=$(prop NRestarts) state=$(systemctl is-active sempose) MainPID=$(prop MainPID) (was $old); $(journalctl -u sempose --no-pager -o cat 2>/dev/null | tail -n 5 | tr '\n' ';')"
  kill -CONT "$old" 2>/dev/null
fi

# 5. A clean stop: SIGTERM, the stages drain, exit 0, the summary in the journal.
systemctl stop sempose
res=$(prop Result); st=$(prop ExecMainStatus)
summ=$(journalctl -u sempose --no-pager -o cat 2>/dev/null | grep '^summary:' | tail -n1)
case "$summ" in *rt_allocs=0*) ok_allocs=1 ;; *) ok_allocs=0 ;; esac
if [ "$res" = success ] && [ "$st" = 0 ] && [ $ok_allocs = 1 ]; then
  check clean_stop PASS "Result=success ExecMainStatus=0; $(echo "$summ" | cut -c1-160)"
else
  check clean_stop FAIL "Result=$res ExecMainStatus=$st summary: '$(echo "$summ" | cut -c1-200)'"
fi

journalctl -b --no-pager -o short-monotonic > /dev/ttyS0 2>&1 || true   # the console log keeps the boot's journal
if [ -z "$FAILED" ]; then say "VERDICT PASS"; v='\000'; else say "VERDICT FAIL$FAILED"; v='\001'; fi
sync
printf "$v" | dd of=/dev/port bs=1 seek=244 count=1 2>/dev/null
systemctl poweroff --force --force
