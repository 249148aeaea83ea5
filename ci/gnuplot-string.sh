# Sourced by the ci/plot-* scripts. Text from outside (a file name, a histogram's series names)
# as a gnuplot single-quoted string: a quote doubled (gnuplot's only escape there) and control
# characters shown as '?'. Pasted unquoted, a histogram whose series was named
# "a';system('touch x');print'" was a command gnuplot ran (hostile round 10).
gnuplot_string() {
  local s=${1//\'/\'\'}
  s=$(printf '%s' "$s" | tr '\001-\037\177' '?')
  printf "'%s'" "$s"
}

# A PNG ends with its IEND chunk; anything else gnuplot left is no picture (a failed or cut
# plot left a 0-byte file behind, exit 1).
png_is_whole() {
  [ -s "$1" ] && [ "$(tail -c 8 "$1" | head -c 4)" = "IEND" ]
}
