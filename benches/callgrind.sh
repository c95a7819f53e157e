#!/usr/bin/env bash
# Instructions per controller step, per configuration, counted by callgrind.
#
#   benches/callgrind.sh                 every configuration (count_steps --list)
#   benches/callgrind.sh unicycle-f64-a  some of them
#   benches/callgrind.sh --functions unicycle-f64-a
#                                        and where one step's instructions go, function by
#                                        function of the core (callgrind_functions.py; needs
#                                        python3 and addr2line)
#   KEEP=dir benches/callgrind.sh ...    keep the callgrind.out files in dir (for
#                                        callgrind_annotate)
#
# Each configuration runs `count_steps CONFIG 1` and `count_steps CONFIG 2` under
# callgrind: the same setup (the recorded closed loop) followed by one or two passes over the
# ~4 096 recorded samples. The difference of the two totals is exactly one pass, so
# instructions per step = (I₂ − I₁) / steps of one pass — with no dependence on inlining or
# symbol names, and, unlike a time, on the machine's load. Needs valgrind (scripts/setup).
set -euo pipefail
cd "$(dirname "$0")/.."

command -v valgrind >/dev/null 2>&1 || { echo "callgrind.sh: valgrind not found (run scripts/setup)" >&2; exit 1; }

target=${CARGO_TARGET_DIR:-target}
cargo build --release --quiet -p companion-benches --bin count_steps
bin="$target/release/count_steps"

functions=0
if [ "${1:-}" = "--functions" ]; then
  functions=1
  shift
fi
if [ $# -gt 0 ]; then
  configs=("$@")
else
  mapfile -t configs < <("$bin" --list)
fi

work=${KEEP:-}
if [ -z "$work" ]; then
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
else
  mkdir -p "$work"
fi

# count CONFIG PASSES: runs under callgrind; leaves $work/CONFIG.PASSES.{out,txt}.
count() {
  valgrind --tool=callgrind --dump-instr=$dump --callgrind-out-file="$work/$1.$2.out" "$bin" "$1" "$2" \
    >"$work/$1.$2.txt" 2>"$work/$1.$2.err" || {
    echo "callgrind.sh: count_steps $1 $2 failed:" >&2
    cat "$work/$1.$2.err" "$work/$1.$2.txt" >&2
    return 1
  }
}
dump=no
[ $functions = 1 ] && dump=yes
total() { awk '/^(summary|totals):/ { print $2; exit }' "$work/$1.out"; }
steps() { awk '{ print $2; exit }' "$work/$1.txt"; }

printf '%-18s %7s %18s\n' "configuration" "steps" "instructions/step"
for c in "${configs[@]}"; do
  count "$c" 1 &
  p1=$!
  count "$c" 2 &
  p2=$!
  wait $p1
  wait $p2
  i1=$(total "$c.1")
  i2=$(total "$c.2")
  s1=$(steps "$c.1")
  s2=$(steps "$c.2")
  awk -v c="$c" -v i1="$i1" -v i2="$i2" -v s1="$s1" -v s2="$s2" \
    'BEGIN { printf "%-18s %7d %18.0f\n", c, s2 - s1, (i2 - i1) / (s2 - s1) }'
  if [ $functions = 1 ]; then
    python3 benches/callgrind_functions.py "$work/$c.1.out" "$work/$c.2.out" $((s2 - s1)) "$bin"
    echo
  fi
done
