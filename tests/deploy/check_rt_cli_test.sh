#!/usr/bin/env bash
# `sempose check-rt` end to end on this machine: one line per check, the kernel line agrees
# with what the kernel says about itself, failures carry their fix, the exit code follows
# the worst line; a bad config is a named error (exit 2); `run --strict-rt` refuses to
# start on a failing box (exit 3) before any output file is touched.
set -euo pipefail
bin=${1:?usage: check_rt_cli_test.sh SEMPOSE}
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }

rc=0; "$bin" check-rt >"$work/out.txt" 2>&1 || rc=$?
cat "$work/out.txt"
summary=$(tail -n1 "$work/out.txt")
[[ $summary =~ ^check-rt:\ ([0-9]+)\ pass,\ ([0-9]+)\ warn,\ ([0-9]+)\ fail$ ]] && ok "summary line" || bad "summary: $summary"
lines=$(grep -cE '^(PASS|WARN|FAIL)  ' "$work/out.txt")
[ "$lines" -ge 12 ] && ok "$lines check lines" || bad "only $lines check lines"
if grep -E '^(WARN|FAIL)  ' "$work/out.txt" | grep -qv -- '-- fix: '; then bad "a WARN/FAIL line without its fix"; else ok "every WARN/FAIL has a fix"; fi
n_fail=$(grep -c '^FAIL  ' "$work/out.txt" || true); n_warn=$(grep -c '^WARN  ' "$work/out.txt" || true)
want=0; [ "$n_warn" -gt 0 ] && want=1; [ "$n_fail" -gt 0 ] && want=3
[ "$rc" -eq "$want" ] && ok "exit code $rc ($n_fail fail, $n_warn warn)" || bad "exit code $rc, expected $want"
if [ "$(cat /sys/kernel/realtime 2>/dev/null)" = 1 ] || uname -v | grep -q PREEMPT_RT; then
  grep -q '^PASS  kernel .*PREEMPT_RT kernel' "$work/out.txt" && ok "RT kernel reported" || bad "RT kernel not reported"
else
  grep -q '^FAIL  kernel .*is not PREEMPT_RT.*-- fix: apt-get install linux-image-rt-amd64' "$work/out.txt" \
    && ok "non-RT kernel fails with the fix" || bad "non-RT kernel not failed with its fix"
fi

# An empty root: nothing readable, so the kernel and limits checks fail.
mkdir -p "$work/empty"
rc=0; "$bin" check-rt --root "$work/empty" >"$work/empty.txt" 2>&1 || rc=$?
[ "$rc" -eq 3 ] && grep -q '^FAIL  kernel' "$work/empty.txt" && ok "empty tree: exit 3" || bad "empty tree: rc $rc"

# A --root that is no directory: named error, exit 2 (not a report on a tree that is not there).
rc=0; "$bin" check-rt --root "$work/nowhere" >"$work/nowhere.txt" 2>&1 || rc=$?
[ "$rc" -eq 2 ] && grep -q "root '$work/nowhere' is not a directory" "$work/nowhere.txt" && ok "missing --root: exit 2" \
  || { cat "$work/nowhere.txt"; bad "missing --root: rc $rc"; }

# A bad config: named error, exit 2.
printf 'pipeline:\n  acquisition: {cpu: 2000, priority: 60}\n' >"$work/bad.yaml"
rc=0; "$bin" check-rt --config "$work/bad.yaml" >"$work/bad.txt" 2>&1 || rc=$?
[ "$rc" -eq 2 ] && grep -q 'bad.yaml:2:.*pipeline.acquisition.cpu: 2000 is outside the allowed range \[-1, 1023\]' "$work/bad.txt" \
  && ok "bad config: exit 2 naming the key" || { cat "$work/bad.txt"; bad "bad config: rc $rc"; }

# An output this user cannot write is a FAIL line among the checks (exit 3), not a config error
# that hides them (exit 2).
printf 'output: {poses_csv: /proc/sempose-nowhere/poses.csv}\n' >"$work/unwritable.yaml"
rc=0; "$bin" check-rt --config "$work/unwritable.yaml" >"$work/unwritable.txt" 2>&1 || rc=$?
if [ "$rc" -eq 3 ] && grep -q "^FAIL  outputs .*output.poses_csv: '/proc/sempose-nowhere/poses.csv' cannot be written" "$work/unwritable.txt" \
   && [ "$(grep -cE '^(PASS|WARN|FAIL)  ' "$work/unwritable.txt")" -eq "$((lines + 1))" ]; then
  ok "unwritable output: its own FAIL line among all $((lines + 1)) checks, exit 3"
else
  cat "$work/unwritable.txt"; bad "unwritable output: rc $rc"
fi

# --strict-rt runs the same checks first and refuses on a failure, writing nothing.
if [ "$want" -eq 3 ]; then
  printf 'output: {poses_csv: %s/poses.csv, hist_dir: %s/hist}\ncan: {log_file: %s/can.log}\nsim: {clock: virtual}\n' \
    "$work" "$work" "$work" >"$work/strict.yaml"
  rc=0; "$bin" run --config "$work/strict.yaml" --strict-rt --duration 1 >"$work/strict.txt" 2>&1 || rc=$?
  if [ "$rc" -eq 3 ] && grep -q 'refusing to start' "$work/strict.txt" && [ ! -e "$work/poses.csv" ] && [ ! -e "$work/can.log" ]; then
    ok "--strict-rt refuses (exit 3) before touching outputs"
  else
    cat "$work/strict.txt"; bad "--strict-rt: rc $rc"
  fi
fi
[ "$fails" -eq 0 ] && echo "check_rt_cli: all passed" || { echo "check_rt_cli: $fails failed"; exit 1; }
