#!/usr/bin/env bash
# The Debian package end to end on this machine: CPack builds it from the build folder; its
# control data declares the shared libraries the binary links and the conffile; dpkg -i
# installs it (user, folders, unit, udev rule, data); the unit passes `systemd-analyze
# verify` and gets its `systemd-analyze security` exposure printed; `sempose run --config
# /etc/sempose/sempose.yaml` runs with the unit's identity, capabilities and limits (user
# sempose, CAP_SYS_NICE + CAP_IPC_LOCK ambient, LimitMEMLOCK, LimitRTPRIO, its working
# folder); an edited conffile survives reinstalling; purge removes everything it made.
# Needs root and dpkg; exits 77 (skip) otherwise, or if a sempose package it did not
# install is present.
set -euo pipefail
build=${1:?usage: package_test.sh BUILD_DIR [SOURCE_DIR]}
src=${2:-}
[ "$(id -u)" -eq 0 ] || { echo "skip: needs root for dpkg -i"; exit 77; }
command -v dpkg-deb >/dev/null && command -v cpack >/dev/null || { echo "skip: dpkg or cpack missing"; exit 77; }
if dpkg-query -W -f='${Status}' sempose 2>/dev/null | grep -q "install ok installed"; then
  echo "skip: a sempose package is already installed here; not touching it"; exit 77
fi
fails=0
ok() { echo "ok   $*"; }
bad() { echo "FAIL $*"; fails=$((fails + 1)); }
installed=0
cleanup() { if [ "$installed" = 1 ]; then dpkg --purge sempose >/dev/null 2>&1 || true; fi; }
trap cleanup EXIT

(cd "$build" && rm -rf packages && cpack -G DEB >cpack.log 2>&1) || { cat "$build/cpack.log"; echo "FAIL cpack"; exit 1; }
deb=$(ls "$build"/packages/sempose_*.deb)
ok "built $(basename "$deb") ($(du -h "$deb" | cut -f1))"
depends=$(dpkg-deb --field "$deb" Depends)
echo "     Depends: $depends"
for lib in libfftw3-single3 libyaml-cpp0.7 libgpiod2 libpng16-16 libstdc++6 libc6; do
  [[ $depends == *"$lib"* ]] && ok "depends on $lib (from the linked libraries)" || bad "Depends lacks $lib"
done
[[ $depends == *opencv* ]] && bad "depends on OpenCV (only the benchmark links it)" || ok "no OpenCV dependency"
[ "$(dpkg-deb --ctrl-tarfile "$deb" | tar -xO ./conffiles)" = /etc/sempose/sempose.yaml ] && ok "conffile /etc/sempose/sempose.yaml" || bad "conffiles"
contents=$(dpkg-deb --contents "$deb" | awk '{print $6}')
for f in ./usr/bin/sempose ./etc/sempose/sempose.yaml ./usr/share/sempose/sempose.dbc ./usr/share/sempose/examples/demo.yaml \
         ./usr/share/sempose/examples/production.yaml ./usr/share/sempose/data/sem/needle_contact_eb.pgm \
         ./usr/share/sempose/data/sem/LICENSE-autoliftout-MIT.txt ./lib/systemd/system/sempose.service \
         ./usr/lib/sysusers.d/sempose.conf ./usr/lib/tmpfiles.d/sempose.conf ./usr/lib/udev/rules.d/60-sempose.rules \
         ./usr/share/doc/sempose/copyright; do
  grep -qx -- "$f" <<<"$contents" || bad "package lacks $f"
done
ok "package holds binary, conffile, DBC, examples, data with its MIT notice, unit, sysusers/tmpfiles/udev, copyright"

dpkg -i "$deb" >"$build/dpkg.log" 2>&1 || { cat "$build/dpkg.log"; bad "dpkg -i"; exit 1; }
installed=1
ok "dpkg -i"
getent passwd sempose >/dev/null && ok "system user $(getent passwd sempose | cut -d: -f1,3,6,7)" || bad "no user sempose"
[ "$(stat -c %U /var/log/sempose 2>/dev/null)" = sempose ] && ok "/var/log/sempose owned by sempose" || bad "/var/log/sempose"

unit=/lib/systemd/system/sempose.service
verify=$(systemd-analyze verify "$unit" 2>&1 | grep -i sempose || true)
[ -z "$verify" ] && ok "systemd-analyze verify: clean" || { echo "$verify"; bad "systemd-analyze verify"; }
exposure=$(systemd-analyze security --offline=true "$unit" 2>/dev/null | tail -n1 || true)
echo "     systemd-analyze security: ${exposure#→ }"

# The unit's settings, without a running systemd: its user and groups, ambient capabilities
# (and nothing else in the bounding set), no new privileges, its limits and working folder.
limits=(prlimit --memlock=unlimited:unlimited --rtprio=99:99 --rttime=unlimited:unlimited)
if ! "${limits[@]}" true 2>/dev/null; then
  # Raising hard limits needs CAP_SYS_RESOURCE, which some containers withhold even from root.
  echo "     note: cannot raise rlimits here (no CAP_SYS_RESOURCE): LimitMEMLOCK/LimitRTPRIO not applied; the two capabilities carry the run alone"
  limits=()
fi
# As on a machine without this source tree: a private mount namespace hides the source's
# config/ (the binary's last fallback for built-in data), so the run must find the simulator's
# texture in /usr/share/sempose/data, where the package put it.
hide=()
if [ -n "$src" ] && unshare --mount --propagation private true 2>/dev/null; then
  hide=(unshare --mount --propagation private -- sh -c 'mount -t tmpfs none "$0/config" && shift && exec "$@"' "$src" x)
  echo "     source tree's config/ hidden from the run (tmpfs in a private mount namespace)"
else
  echo "     note: cannot hide the source tree here (no unshare); the run may fall back to it"
fi
cd /var/lib/sempose
rc=0
"${hide[@]}" "${limits[@]}" setpriv --reuid=sempose --regid=sempose --init-groups --no-new-privs \
    --inh-caps=-all,+sys_nice,+ipc_lock --ambient-caps=-all,+sys_nice,+ipc_lock --bounding-set=-all,+sys_nice,+ipc_lock \
    sempose run --config /etc/sempose/sempose.yaml --hist-dir /var/log/sempose --duration 3 >"$build/package_run.log" 2>&1 || rc=$?
cd - >/dev/null
grep -E '^(thread|warning|summary)' "$build/package_run.log" | cut -c1-160 || true
summary=$(tail -n1 "$build/package_run.log")
if [ "$rc" -eq 0 ] && [[ $summary == summary:* && $summary == *" rt_allocs=0 "* && $summary != *"poses=0 "* ]]; then
  ok "sempose run --config /etc/sempose/sempose.yaml as sempose: exit 0, poses, rt_allocs=0"
else
  tail -n 20 "$build/package_run.log"; bad "packaged run: rc $rc"
fi
grep -q '^thread acquisition: SCHED_FIFO 60' "$build/package_run.log" && ok "SCHED_FIFO as user sempose" || bad "no SCHED_FIFO"
if grep -q 'mlockall failed' "$build/package_run.log"; then bad "memory not locked"; else ok "memory locked"; fi
[ -s /var/log/sempose/latency_hist.txt ] && [ -s /var/log/sempose/sempose_can.log ] && [ "$(stat -c %U /var/log/sempose/sempose_can.log)" = sempose ] \
  && ok "histograms and CAN log in /var/log/sempose, owned by sempose" || bad "outputs in /var/log/sempose"

# Conffile: a local edit survives reinstalling the same package.
echo "# local edit" >>/etc/sempose/sempose.yaml
dpkg -i "$deb" >>"$build/dpkg.log" 2>&1 </dev/null || bad "reinstall"
grep -q '^# local edit' /etc/sempose/sempose.yaml && ok "edited conffile kept on reinstall" || bad "conffile overwritten"

dpkg --purge sempose >>"$build/dpkg.log" 2>&1 || bad "dpkg --purge"
installed=0
for p in /usr/bin/sempose /etc/sempose /usr/share/sempose /var/log/sempose /var/lib/sempose /lib/systemd/system/sempose.service; do
  [ ! -e "$p" ] || bad "$p left after purge"
done
ok "purged: binary, config, data, unit, logs gone"
[ "$fails" -eq 0 ] && echo "package_install: all passed" || { echo "package_install: $fails failed"; exit 1; }
