#!/usr/bin/env bash
# ci/plot-latency on hostile histograms (hostile round 10): series names and the file's name are
# gnuplot strings, never commands (a series named "a';system('touch …');print'" ran); a histogram
# gnuplot cannot draw leaves no PNG behind (a 0-byte one was left, exit 1); the user's ~/.gnuplot
# is not read. Usage: plot_scripts_test.sh SOURCE_DIR
set -u
src=${1:?usage: plot_scripts_test.sh SOURCE_DIR}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail=0
check() { if ! eval "$2"; then echo "FAIL: $1"; fail=1; else echo "ok: $1"; fi; }

cat > "$work/it's h.txt" <<H
# sempose latency histogram, 1 us buckets; series: a';system('touch $work/ran');print' b"\`touch $work/ran2\`"
# Histogram
000000 000005 000001
000001 000003 000002
000002 000000 000004
# Max Latencies: 00001 00002
H
mkdir -p "$work/home"
printf 'set datafile separator ","\n' > "$work/home/.gnuplot"
HOME="$work/home" bash "$src/ci/plot-latency" "$work/it's h.txt" "$work/out'1.png"; rc=$?
check "a hostile histogram is drawn (rc $rc)" '[ $rc -eq 0 ]'
check "no command in a series name ran" '[ ! -e "$work/ran" ] && [ ! -e "$work/ran2" ]'
check "the picture is a whole PNG" '[ "$(tail -c 8 "$work/out'"'"'1.png" | head -c 4)" = IEND ]'

printf '# series: x\n000000 -5\n000001 nan\n000002 1e400\n' > "$work/junk.txt"
bash "$src/ci/plot-latency" "$work/junk.txt" "$work/junk.png"; rc=$?
check "junk counts fail (rc $rc)" '[ $rc -eq 1 ]'
check "no picture left from a failed plot" '[ ! -e "$work/junk.png" ]'
exit $fail
