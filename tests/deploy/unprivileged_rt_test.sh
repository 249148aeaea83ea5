#!/usr/bin/env bash
# sempose run as an unprivileged user (nobody) holding only CAP_SYS_NICE and CAP_IPC_LOCK as
# ambient capabilities (setpriv; what the unit's AmbientCapabilities= gives): the kernel must
# show its RT threads as SCHED_FIFO on their cores and its memory locked, with no root and no
# raised rlimits (RLIMIT_RTPRIO 0, RLIMIT_MEMLOCK 8 MiB stay). Control: the same run without
# the capabilities must report both as missing, so the test can tell the difference.
set -euo pipefail
bin=${1:?usage: unprivileged_rt_test.sh SEMPOSE}
[ "$(id -u)" -eq 0 ] || { echo "skip: needs root to drop to nobody with setpriv"; exit 77; }
command -v setpriv >/dev/null || { echo "skip: setpriv (util-linux) missing"; exit 77; }
chrt -f 1 true 2>/dev/null || { echo "skip: SCHED_FIFO not available here even for root"; exit 77; }
work=$(mktemp -d); chmod 755 "$work"; trap 'rm -rf "$work"' EXIT
mkdir -m 777 "$work/out"
# The binary must be reachable by nobody (build trees under a 0700 home would not be).
cp "$bin" "$work/sempose"; chmod 755 "$work/sempose"
cpu1=$(( $(nproc) > 1 ? 1 : 0 ))
cat >"$work/run.yaml" <<YAML
sim: {clock: real}
pipeline:
  acquisition: {cpu: 0, priority: 60}
  correlation: {cpu: $cpu1, priority: 50}
  output: {cpu: $cpu1, priority: 40}
  hold_dma_latency: false      # /dev/cpu_dma_latency is root's (the package's udev rule grants it)
  non_rt_cpu: -1
output: {poses_csv: $work/out/poses.csv, hist_dir: $work/out, print_status: false}
can: {log_file: $work/out/can.log}
YAML
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }

# Starts sempose as nobody with the given capability sets; leaves its pid in $pid.
start() {
  setpriv --reuid=nobody --regid=nogroup --clear-groups --no-new-privs "$@" \
    "$work/sempose" run --config "$work/run.yaml" --duration 8 >"$work/out.txt" 2>&1 &
  pid=$!
  for _ in $(seq 1 600); do grep -q '^thread correlation' "$work/out.txt" && return 0; kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  return 1
}

# ---- with the two capabilities
caps=(--inh-caps=-all,+sys_nice,+ipc_lock --ambient-caps=-all,+sys_nice,+ipc_lock --bounding-set=-all,+sys_nice,+ipc_lock)
if start "${caps[@]}"; then
  status=$(cat /proc/$pid/status)
  uid=$(awk '/^Uid:/ {print $2}' <<<"$status"); capeff=$(awk '/^CapEff:/ {print $2}' <<<"$status")
  vmlck=$(awk '/^VmLck:/ {print $2}' <<<"$status"); vmrss=$(awk '/^VmRSS:/ {print $2}' <<<"$status")
  memlock=$(awk '/^Max locked memory/ {print $4}' /proc/$pid/limits); rtprio=$(awk '/^Max realtime priority/ {print $4}' /proc/$pid/limits)
  [ "$uid" = "$(id -u nobody)" ] && ok "runs as nobody (uid $uid)" || bad "uid $uid"
  [ "$capeff" = 0000000000804000 ] && ok "effective capabilities: CAP_SYS_NICE + CAP_IPC_LOCK only ($capeff)" || bad "CapEff $capeff"
  echo "     rlimits untouched: RLIMIT_MEMLOCK soft $memlock, RLIMIT_RTPRIO soft $rtprio"
  # Locked beyond what RLIMIT_MEMLOCK alone would allow: CAP_IPC_LOCK is what made mlockall work.
  [ "${vmlck:-0}" -gt $((memlock / 1024)) ] && ok "memory locked: VmLck $vmlck kB (VmRSS $vmrss kB) > RLIMIT_MEMLOCK $((memlock / 1024)) kB" \
    || bad "VmLck ${vmlck:-?} kB"
  # Bash builtins only (no fork per file): on a loaded 2-core machine the FIFO threads leave
  # little CPU to forked helpers, and the run must still be going while it is inspected.
  fifo=0
  for t in /proc/$pid/task/*; do
    { read -r comm <"$t/comm" && read -r stat <"$t/stat"; } 2>/dev/null || continue  # ended meanwhile
    cpus=?
    while read -r key val; do [ "$key" = Cpus_allowed_list: ] && cpus=$val; done <"$t/status" 2>/dev/null
    read -r -a f <<<"${stat##*) }"   # fields after "pid (comm) ": f[0] is field 3 (state)
    policy=${f[38]}; prio=${f[37]}   # fields 41 (policy) and 40 (rt_priority)
    if [ "$policy" = 1 ]; then
      fifo=$((fifo + 1)); echo "     kernel: thread $comm SCHED_FIFO $prio on cpu $cpus"
    fi
  done
  [ "$fifo" -ge 2 ] && ok "$fifo threads SCHED_FIFO (per /proc/PID/task/*/stat)" || bad "$fifo SCHED_FIFO threads"
  wait "$pid" || bad "sempose exited with $?"
  grep -E '^thread ' "$work/out.txt"
  grep -q '^thread acquisition: SCHED_FIFO 60 on cpu 0' "$work/out.txt" && ok "sempose reports FIFO placement" || bad "placement"
  if grep -E '^warning:.*(SCHED_FIFO|mlockall)' "$work/out.txt"; then bad "RT warnings despite the capabilities"; else ok "no RT warning"; fi
  summary=$(tail -n1 "$work/out.txt")
  [[ $summary == summary:* && $summary == *" rt_allocs=0 "* && $summary != *"poses=0 "* ]] && ok "summary: ${summary:0:80}..." || bad "summary: $summary"
else
  cat "$work/out.txt"; bad "sempose did not start with the capabilities"
fi

# ---- control: no capabilities -> sempose must say both are missing
if start --inh-caps=-all --ambient-caps=-all --bounding-set=-all; then
  wait "$pid" || true
  grep -q "SCHED_FIFO priority 60 not permitted" "$work/out.txt" && grep -q 'mlockall failed' "$work/out.txt" \
    && ok "control without capabilities: FIFO and mlockall refused, as expected" || { cat "$work/out.txt"; bad "control run"; }
else
  cat "$work/out.txt"; bad "control run did not start"
fi
[ "$fails" -eq 0 ] && echo "unprivileged_rt: all passed" || { echo "unprivileged_rt: $fails failed"; exit 1; }
