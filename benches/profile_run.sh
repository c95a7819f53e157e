#!/usr/bin/env bash
# Where the instructions of a whole simulated run go, per step, counted by callgrind.
#
#   benches/profile_run.sh                         trajectory 2, variant (a), 120 s
#   benches/profile_run.sh --choice c --duration 40   any `companion sim` scenario flags
#
# Runs `companion sim ... --no-plots` once under callgrind (one output per thread) and
# prints, per controller step, the instructions of the parts of the loop
# (`companion_runtime::run::sim::run_loop`): controller step, plant step, measurement and sample,
# summary, hand-off of logged rows — whatever the compiler inlined (callgrind_run.py) — and
# of the CSV writer thread. Needs valgrind (scripts/setup), python3 and addr2line; takes
# 10–20 s per 120 s of simulated time.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v valgrind >/dev/null 2>&1 || { echo "profile_run.sh: valgrind not found (run scripts/setup)" >&2; exit 1; }

target=${CARGO_TARGET_DIR:-target}
cargo build --release --quiet -p companion-runtime --bin companion
bin="$target/release/companion"

args=("$@")
[ ${#args[@]} -eq 0 ] && args=(--trajectory 2 --choice a)

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
[ -n "${KEEP:-}" ] && trap - EXIT && echo "keeping $work" >&2
valgrind --tool=callgrind --dump-instr=yes --separate-threads=yes --callgrind-out-file="$work/cg.out" \
  "$bin" sim "${args[@]}" --no-plots --out "$work/run" >"$work/stdout" 2>"$work/stderr" || {
  cat "$work/stderr" >&2
  exit 1
}
steps=$(awk -F'"steps": ' '/"steps"/ { sub(/,.*/, "", $2); print $2 }' "$work/run/summary.json")
# The thread that runs the loop is the one whose output names run_loop or run_one.
main_out=$(grep -l "companion_runtime::run::sim::run_\(loop\|one\)" "$work"/cg.out-* | head -1)
others=()
for f in "$work"/cg.out-*; do
  [ "$f" != "$main_out" ] && [ -s "$f" ] && others+=("$f")
done
echo "companion sim ${args[*]}: $steps steps; instructions per step"
python3 benches/callgrind_run.py "$steps" "$bin" "$main_out" "${others[@]}"
