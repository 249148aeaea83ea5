#!/bin/bash
# build_systemd_initramfs.sh ENV_FILE OUT_IMAGE SEMPOSE_DEB
# The systemd-boot VM's initramfs: a usr-merged root with Debian 12's systemd (the files of
# this machine's `systemd` package, its libraries by ldd), busybox for the test script, the
# sempose Debian package extracted as dpkg would lay it out, the operator's config
# (guest_systemd/sempose.yaml over the conffile) and the test's units. /init (busybox)
# copies it onto a tmpfs and switch_root's into /lib/systemd/systemd, so systemd runs as
# PID 1 on an ordinary root filesystem (its sandboxing needs a mountable, remountable /).
set -euo pipefail
ENV_FILE=${1:?usage: build_systemd_initramfs.sh ENV_FILE OUT_IMAGE SEMPOSE_DEB}
OUT=${2:?}; DEB=${3:?}
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck disable=SC1090
. "$ENV_FILE"
command -v dpkg-query >/dev/null && dpkg-query -W -f='${Status}' systemd 2>/dev/null | grep -q "ok installed" ||
  { echo "build_systemd_initramfs: the systemd package is not installed here (ci/setup installs it)"; exit 1; }
S=$(mktemp -d); trap 'rm -rf "$S"' EXIT
R=$S/root
mkdir -p "$R"/usr/{bin,sbin,lib/x86_64-linux-gnu,lib64} "$R"/{etc,proc,sys,dev,run,tmp,var/log,var/lib,root}
for d in bin sbin lib lib64; do ln -s usr/$d "$R/$d"; done

LIBS=""
add_file() { # add_file PATH: copies it (a symlink as a symlink) to the same path under $R
  local p=$1 dst
  dst=$R$(readlink -m "$(dirname "$p")" | sed 's#^/lib#/usr/lib#; s#^/bin#/usr/bin#; s#^/sbin#/usr/sbin#')/$(basename "$p")
  mkdir -p "$(dirname "$dst")"
  if [ -L "$p" ]; then cp -P "$p" "$dst"; elif [ -f "$p" ]; then cp "$p" "$dst"; else return 0; fi
  if [ -f "$p" ] && [ ! -L "$p" ] && head -c 4 "$p" | grep -q ELF; then LIBS="$LIBS $p"; fi
}
# The systemd and libsystemd-shared packages as installed here (Debian 12: systemd 252),
# without docs and manuals.
while read -r f; do
  case "$f" in /usr/share/doc/*|/usr/share/man/*|/usr/share/locale/*|/usr/share/bash-completion/*|/usr/share/zsh/*) continue ;; esac
  [ -d "$f" ] && [ ! -L "$f" ] && continue
  add_file "$f"
done < <(dpkg-query -L systemd libsystemd-shared)
# Shared libraries of every ELF file copied (systemd's and sempose's), with the loader.
copy_libs() {
  local lib
  for lib in $(ldd "$@" 2>/dev/null | awk '/=> \//{print $3} $1 ~ /^\/.*ld-linux/{print $1}' | sort -u); do
    local real; real=$(readlink -f "$lib")
    local base; base=$(basename "$lib")
    case "$lib" in
      *ld-linux*) [ -e "$R/usr/lib64/$base" ] || cp -L "$real" "$R/usr/lib64/$base" ;;
      */systemd/*) ;;   # libsystemd-shared: copied with the package
      *) [ -e "$R/usr/lib/x86_64-linux-gnu/$base" ] || cp -L "$real" "$R/usr/lib/x86_64-linux-gnu/$base" ;;
    esac
  done
}

# sempose's package, laid out as dpkg would (usr-merged: ./lib -> /usr/lib).
X=$S/deb; mkdir -p "$X"; dpkg-deb -x "$DEB" "$X"
for top in lib bin sbin; do
  if [ -d "$X/$top" ]; then cp -a "$X/$top"/. "$R/usr/$top"/; rm -rf "${X:?}/$top"; fi
done
cp -a "$X"/. "$R"/
LIBS="$LIBS $R/usr/bin/sempose"
copy_libs $LIBS
strip --strip-unneeded "$R"/usr/lib/x86_64-linux-gnu/*.so* 2>/dev/null || true

# busybox for /init and the test script (applets only where systemd has no file).
cp "$ROOT/bin/busybox" "$R/usr/bin/busybox"
for a in $("$R/usr/bin/busybox" --list-full); do
  a=$(echo "$a" | sed 's#^bin/#usr/bin/#; s#^sbin/#usr/sbin/#')
  [ -e "$R/$a" ] || [ -L "$R/$a" ] || ln -s /usr/bin/busybox "$R/$a"
done

# /etc: root only; the sempose user comes from the package's sysusers file at boot.
printf 'root:x:0:0:root:/root:/bin/sh\n' > "$R/etc/passwd"
printf 'root:x:0:\n' > "$R/etc/group"
printf 'passwd: files\ngroup: files\nshadow: files\n' > "$R/etc/nsswitch.conf"
: > "$R/etc/machine-id"
cp /etc/os-release "$R/etc/os-release" 2>/dev/null || cp /usr/lib/os-release "$R/etc/os-release"
# The operator's config over the conffile (a small scene: the VM emulates its CPUs).
cp "$HERE/guest_systemd/sempose.yaml" "$R/etc/sempose/sempose.yaml"
# The test: a target that wants sempose.service and the check, the default target.
mkdir -p "$R/etc/systemd/system"
cp "$HERE/guest_systemd/sempose-systest.target" "$HERE/guest_systemd/sempose-systest.service" "$R/etc/systemd/system/"
ln -sf sempose-systest.target "$R/etc/systemd/system/default.target"
install -D -m 0755 "$HERE/guest_systemd/check.sh" "$R/usr/libexec/sempose-systest-check"
# Where the package's maintainer scripts would have made the sempose unit wanted: the test's
# target pulls it in instead (it is what `systemctl enable` would do for multi-user.target).

# One archive: /init and a busybox for it at the top, the root tree under /image.
O=$S/outer; mkdir -p "$O"/{bin,dev,proc,sys,newroot}
mv "$R" "$O/image"
cp "$ROOT/bin/busybox" "$O/bin/busybox"
install -m 0755 "$HERE/guest_systemd/init" "$O/init"
(cd "$O" && find . -mindepth 1 | LC_ALL=C sort | cpio -o -H newc --quiet -R 0:0) > "$OUT.cpio"
# Device nodes as a second cpio member (no root needed to build this).
/usr/bin/python3 - >> "$OUT.cpio" <<'PY'
import sys
out = sys.stdout.buffer
ino = 900000
def entry(name, mode, rmaj=0, rmin=0):
    global ino
    ino += 1
    nm = name.encode() + b'\0'
    hdr = b'070701' + b''.join(b'%08X' % v for v in (ino, mode, 0, 0, 1, 0, 0, 0, 0, rmaj, rmin, len(nm), 0))
    buf = hdr + nm
    out.write(buf + b'\0' * (-len(buf) % 4))
entry('dev/console', 0o020600, 5, 1)
entry('dev/null', 0o020666, 1, 3)
entry('TRAILER!!!', 0)
PY
gzip -1 -n -c "$OUT.cpio" > "$OUT.tmp"; rm -f "$OUT.cpio"; mv "$OUT.tmp" "$OUT"
echo "[systemd-initramfs] $(du -h "$OUT" | cut -f1) ($(dpkg-query -W -f='${Version}' systemd) systemd, $(basename "$DEB"))"
