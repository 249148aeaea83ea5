#!/bin/bash
# prepare_host.sh CACHE_DIR
# Idempotent host preparation for the sempose system test (issue 7):
#  - fetches Debian's PREEMPT_RT kernel (ABI resolved at run time), busybox-static,
#    can-utils, gpiod/libgpiod2, rt-tests and linux-source-6.1 with `apt-get download`;
#  - extracts the kernel, its modules and an uncompressed ELF vmlinux (PVH boot);
#  - builds gpio-sim (+ irq_sim) and the emulated-SEM Comedi driver (kmod/sem_emul.c) out of
#    tree against linux-headers-<KVER>;
#  - writes CACHE_DIR/current.env describing the result (KVER, paths).
# Needs root only to apt-get install linux-headers-<KVER> (and gcc/make) when absent.
set -euo pipefail
CACHE=${1:?usage: prepare_host.sh CACHE_DIR}
mkdir -p "$CACHE"
CACHE=$(cd "$CACHE" && pwd)
HERE=$(cd "$(dirname "$0")" && pwd)
log() { echo "[prepare] $*" >&2; }

# Serialise concurrent runs on one cache.
exec 9>"$CACHE/.lock"
flock 9

KPKG=$(apt-cache depends linux-image-rt-amd64 2>/dev/null |
       awk '/Depends: linux-image-[0-9]/{print $2; exit}')
if [ -z "$KPKG" ]; then
  # No apt metadata? Fall back to whatever a previous run prepared.
  if [ -f "$CACHE/current.env" ]; then
    log "apt-cache cannot resolve linux-image-rt-amd64; reusing $CACHE/current.env"
    exit 0
  fi
  log "cannot resolve linux-image-rt-amd64 (run apt-get update?)"; exit 1
fi
KVER=${KPKG#linux-image-}
KPKG_VER=$(apt-cache policy "$KPKG" | awk '/Candidate:/{print $2; exit}')
log "kernel package $KPKG ($KPKG_VER), KVER=$KVER"

DEBS="$CACHE/debs"; mkdir -p "$DEBS"
fetch() { # fetch PKG[=VER] -> prints the .deb path
  local spec=$1 name=${1%%=*} f
  f=$(ls "$DEBS"/"${name}"_*.deb 2>/dev/null | head -1 || true)
  if [ -n "$f" ] && [[ "$spec" != *=* || "$f" == *"_${spec#*=}_"* || "$f" == *"_$(echo "${spec#*=}" | sed 's/:/%3a/')_"* ]]; then
    echo "$f"; return
  fi
  log "apt-get download $spec"
  (cd "$DEBS" && apt-get download -q "$spec" >&2)
  ls -t "$DEBS"/"${name}"_*.deb | head -1
}

PKGS="busybox-static can-utils gpiod libgpiod2 rt-tests libnuma1 util-linux"  # util-linux: chrt
ROOT="$CACHE/root-$KVER"          # all extracted packages (tools + kernel)
STAMP="$ROOT/.extracted-$(echo "$PKGS" | md5sum | cut -c1-8)"
if [ ! -f "$STAMP" ]; then
  rm -rf "$ROOT"; mkdir -p "$ROOT"
  for p in "$KPKG=$KPKG_VER" $PKGS; do
    deb=$(fetch "$p")
    log "extract $(basename "$deb")"
    dpkg-deb -x "$deb" "$ROOT"
  done
  touch "$STAMP"
fi

# Uncompressed ELF vmlinux from vmlinuz (xz payload) for qemu's PVH entry.
VMLINUZ="$ROOT/boot/vmlinuz-$KVER"
VMLINUX="$CACHE/vmlinux-$KVER"
if [ ! -s "$VMLINUX" ]; then
  off=$(/usr/bin/python3 - "$VMLINUZ" <<'PY'
import sys
d = open(sys.argv[1], 'rb').read()
i = d.find(b'\xfd7zXZ\x00')
print(i)
PY
)
  [ "$off" -ge 0 ] || { log "no xz payload in $VMLINUZ"; exit 1; }
  log "extract vmlinux (xz at offset $off)"
  tail -c +$((off + 1)) "$VMLINUZ" | xz -dc --single-stream > "$VMLINUX.tmp" 2>/dev/null || true
  head -c 4 "$VMLINUX.tmp" | grep -q ELF || { log "vmlinux extraction failed"; exit 1; }
  mv "$VMLINUX.tmp" "$VMLINUX"
fi

# Out-of-tree modules (gpio-sim, the emulated-SEM Comedi driver) build against the headers.
HDR="/usr/src/linux-headers-$KVER"
need_headers() {
  if [ ! -f "$HDR/Makefile" ]; then
    log "apt-get install linux-headers-$KVER"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
      "linux-headers-$KVER=$KPKG_VER" gcc make >&2
  fi
}
# The few kernel source files the modules need, from linux-source-6.1 (fetched once, 139 MB,
# deleted after extraction): gpio-sim + irq_sim, and Comedi's driver-side headers
# (include/linux/comedi/*.h are not in the headers package).
SRCDIR="$CACHE/linux-source-gpio-sim-$KPKG_VER"
COMEDI_SRC="$CACHE/linux-source-comedi-$KPKG_VER"
if [ ! -f "$SRCDIR/irq_sim.c" ] || [ ! -f "$COMEDI_SRC/include/linux/comedi/comedidev.h" ]; then
  deb=$(fetch "linux-source-6.1=$KPKG_VER")
  log "extract gpio-sim and comedi sources from $(basename "$deb")"
  tmp=$(mktemp -d); mkdir -p "$SRCDIR" "$COMEDI_SRC"
  dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$tmp" --wildcards './usr/src/linux-source-6.1.tar.xz'
  tar -xJf "$tmp/usr/src/linux-source-6.1.tar.xz" -C "$tmp" \
    linux-source-6.1/drivers/gpio/gpio-sim.c linux-source-6.1/drivers/gpio/gpiolib.h \
    linux-source-6.1/kernel/irq/irq_sim.c linux-source-6.1/include/linux/comedi \
    linux-source-6.1/drivers/comedi/drivers/comedi_test.c
  cp "$tmp"/linux-source-6.1/drivers/gpio/{gpio-sim.c,gpiolib.h} "$tmp"/linux-source-6.1/kernel/irq/irq_sim.c "$SRCDIR/"
  mkdir -p "$COMEDI_SRC/include/linux"
  cp -r "$tmp"/linux-source-6.1/include/linux/comedi "$COMEDI_SRC/include/linux/"
  cp "$tmp"/linux-source-6.1/drivers/comedi/drivers/comedi_test.c "$COMEDI_SRC/"
  rm -rf "$tmp"
  rm -f "$deb"   # 139 MB for a few files: keep only those
fi

# gpio-sim out of tree (Debian's RT kernel has CONFIG_GPIO_SIM / IRQ_SIM unset).
GPIOSIM="$CACHE/gpio-sim-$KVER.ko"
if [ ! -s "$GPIOSIM" ]; then
  need_headers
  B=$(mktemp -d)
  cp "$SRCDIR/gpio-sim.c" "$B/gpio-sim-main.c"
  cp "$SRCDIR/gpiolib.h" "$B/"
  # irq_to_desc is not exported to modules: dispatch through generic_handle_irq_safe.
  sed 's/handle_simple_irq(irq_to_desc(\([^)]*\)))/generic_handle_irq_safe(\1)/' \
    "$SRCDIR/irq_sim.c" > "$B/irq_sim.c"
  grep -q 'generic_handle_irq_safe' "$B/irq_sim.c" || { log "irq_sim.c patch did not apply"; exit 1; }
  cat > "$B/Makefile" <<'MK'
obj-m := gpio-sim.o
gpio-sim-y := gpio-sim-main.o irq_sim.o
MK
  log "build gpio-sim.ko against $HDR"
  make -s -C "$HDR" M="$B" modules >&2
  cp "$B/gpio-sim.ko" "$GPIOSIM.tmp" && mv "$GPIOSIM.tmp" "$GPIOSIM"
  rm -rf "$B"
fi

# The emulated SEM behind Comedi (kmod/sem_emul.c), built against the headers plus Comedi's
# driver-side headers from linux-source; cached per kernel and source checksum.
SEM_SUM=$(md5sum "$HERE/kmod/sem_emul.c" | cut -c1-8)
SEMEMUL="$CACHE/sem_emul-$KVER-$SEM_SUM.ko"
if [ ! -s "$SEMEMUL" ]; then
  need_headers
  B=$(mktemp -d)
  cp "$HERE/kmod/sem_emul.c" "$B/"
  printf 'obj-m := sem_emul.o\nccflags-y := -I%s/include\n' "$COMEDI_SRC" > "$B/Makefile"
  log "build sem_emul.ko against $HDR"
  make -s -C "$HDR" M="$B" modules >&2
  cp "$B/sem_emul.ko" "$SEMEMUL.tmp" && mv "$SEMEMUL.tmp" "$SEMEMUL"
  rm -rf "$B"
fi

cat > "$CACHE/current.env.tmp" <<ENV
KVER=$KVER
ROOT=$ROOT
VMLINUX=$VMLINUX
VMLINUZ=$VMLINUZ
GPIOSIM=$GPIOSIM
SEMEMUL=$SEMEMUL
ENV
mv "$CACHE/current.env.tmp" "$CACHE/current.env"
log "ready: $(cat "$CACHE/current.env" | tr '\n' ' ')"
