#!/bin/bash
# build_initramfs.sh ENV_FILE OUT_IMAGE GUEST_CFG_DIR [SEMPOSE_BINARY [CAN_GPIO_HW_TEST [COMEDI_HW_TEST]]]
# Builds the gzip'd newc initramfs for the system-test VM from what prepare_host.sh
# extracted (ENV_FILE = CACHE/current.env): busybox + applet links, the kernel modules
# (incl. the out-of-tree gpio-sim), can-utils, gpiod tools, cyclictest, sempose and
# can_gpio_hw_test (optional)
# and all their shared libraries (ldd, incl. the dynamic loader), /init and the guest
# test script. GUEST_CFG_DIR is copied to /cfg. No root needed: the device nodes
# (/dev/console, /dev/null) go into a second, hand-written cpio member.
set -euo pipefail
ENV_FILE=${1:?}; OUT=${2:?}; CFG=${3:?}; SEMPOSE=${4:-}; HWTEST=${5:-}; COMEDI_HWTEST=${6:-}
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck disable=SC1090
. "$ENV_FILE"
M="$ROOT/lib/modules/$KVER/kernel"
S=$(mktemp -d); trap 'rm -rf "$S"' EXIT
mkdir -p "$S"/{bin,sbin,usr/bin,usr/sbin,lib/x86_64-linux-gnu,lib64,modules,proc,sys,dev,tmp,out,cfg,run,var,etc}

cp "$ROOT/bin/busybox" "$S/bin/busybox"
for a in $("$S/bin/busybox" --list-full); do
  [ -e "$S/$a" ] || ln -s /bin/busybox "$S/$a"
done

for m in drivers/net/can/dev/can-dev drivers/net/can/vcan net/can/can net/can/can-raw fs/configfs/configfs \
         drivers/comedi/comedi drivers/comedi/drivers/comedi_test; do
  f=$(ls "$M/$m".ko* | head -1)
  case "$f" in
    *.xz) xz -dc "$f" > "$S/modules/$(basename "$m").ko" ;;
    *.zst) zstd -dcq "$f" > "$S/modules/$(basename "$m").ko" ;;
    *) cp "$f" "$S/modules/" ;;
  esac
done
cp "$GPIOSIM" "$S/modules/gpio-sim.ko"
cp "$SEMEMUL" "$S/modules/sem_emul.ko"
strip --strip-debug "$S"/modules/*.ko 2>/dev/null || true

LIBPATH="$ROOT/usr/lib/x86_64-linux-gnu:$ROOT/lib/x86_64-linux-gnu"
add_bin() { # add_bin SRC DEST
  local src=$1 dst=$2 lib
  install -m 0755 "$src" "$S/$dst"
  strip --strip-unneeded "$S/$dst" 2>/dev/null || true
  # ldd lines: "libx.so => /path (0x..)" or "/lib64/ld-linux-x86-64.so.2 (0x..)"
  for lib in $(LD_LIBRARY_PATH="$LIBPATH" ldd "$src" 2>/dev/null |
               awk '/=> \//{print $3} $1 ~ /^\/.*ld-linux/{print $1}'); do
    case "$lib" in
      *ld-linux*) [ -e "$S/lib64/$(basename "$lib")" ] || cp -L "$lib" "$S/lib64/" ;;
      *) [ -e "$S/lib/x86_64-linux-gnu/$(basename "$lib")" ] || cp -L "$lib" "$S/lib/x86_64-linux-gnu/" ;;
    esac
  done
}
for t in candump cansend cangen canplayer; do add_bin "$ROOT/usr/bin/$t" "usr/bin/$t"; done
for t in gpioset gpioget gpiomon gpioinfo gpiodetect; do add_bin "$ROOT/usr/bin/$t" "usr/bin/$t"; done
add_bin "$ROOT/usr/bin/cyclictest" usr/bin/cyclictest
add_bin "$ROOT/usr/bin/chrt" usr/bin/chrt
if [ -n "$SEMPOSE" ] && [ -x "$SEMPOSE" ]; then
  add_bin "$SEMPOSE" usr/bin/sempose
fi
if [ -n "$HWTEST" ] && [ -x "$HWTEST" ]; then
  add_bin "$HWTEST" usr/bin/can_gpio_hw_test
fi
if [ -n "$COMEDI_HWTEST" ] && [ -x "$COMEDI_HWTEST" ]; then
  add_bin "$COMEDI_HWTEST" usr/bin/comedi_hw_test
fi
strip --strip-unneeded "$S"/lib/x86_64-linux-gnu/* 2>/dev/null || true

install -m 0755 "$HERE/guest/init" "$S/init"
install -m 0755 "$HERE/guest/guest_test.sh" "$S/bin/guest_test.sh"
cp -r "$CFG"/. "$S/cfg/"
# sem_emul's scene goes through the firmware loader (direct load from /lib/firmware).
if [ -f "$CFG/sem_scene.pgm" ]; then mkdir -p "$S/lib/firmware"; cp "$CFG/sem_scene.pgm" "$S/lib/firmware/"; fi
echo "root:x:0:0:root:/:/bin/sh" > "$S/etc/passwd"

(cd "$S" && find . -mindepth 1 | LC_ALL=C sort | cpio -o -H newc --quiet -R 0:0) > "$OUT.cpio"
# Device nodes as a second cpio member (the kernel concatenates them).
/usr/bin/python3 - >> "$OUT.cpio" <<'PY'
import sys, os
out = sys.stdout.buffer
ino = 900000
def entry(name, mode, rmaj=0, rmin=0, data=b''):
    global ino
    ino += 1
    nm = name.encode() + b'\0'
    hdr = b'070701' + b''.join(b'%08X' % v for v in (
        ino, mode, 0, 0, 1, 0, len(data), 0, 0, rmaj, rmin, len(nm), 0))
    buf = hdr + nm
    buf += b'\0' * (-len(buf) % 4)
    buf += data + b'\0' * (-len(data) % 4)
    out.write(buf)
entry('dev', 0o040755)
entry('dev/console', 0o020600, 5, 1)
entry('dev/null', 0o020666, 1, 3)
entry('dev/ttyS0', 0o020600, 4, 64)
entry('dev/ttyS1', 0o020600, 4, 65)
entry('TRAILER!!!', 0)
PY
gzip -6 -n < "$OUT.cpio" > "$OUT.tmp"
rm -f "$OUT.cpio"
mv "$OUT.tmp" "$OUT"
echo "[initramfs] $OUT: $(du -h "$OUT" | cut -f1) (sempose: ${SEMPOSE:-none}, hw test: ${HWTEST:-none})" >&2
