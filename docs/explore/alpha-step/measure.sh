#!/usr/bin/env bash
# Measures the variants of the α step tried for issue 25 (README.md beside this script):
# in a scratch checkout of the commit the patch was made on, with `variants.patch` applied
# (a switch LAW_VARIANT/LAW_PARAM in companion-core, LAW_IC in companion-plant, the
# example `alpha_probe`):
#
#   git worktree add /tmp/alpha <commit> && cd /tmp/alpha
#   git apply docs/explore/alpha-step/variants.patch
#   docs/explore/alpha-step/measure.sh OUT [VARIANT...]     # ~6 min per variant on 2 cores
#   docs/explore/alpha-step/tables.py OUT                   # the tables
#
# Per variant, into OUT/<variant>/: the pointwise distances at 1 and 0.5 ms (pointwise.txt,
# the RK4 references cached in OUT/ref-*.bin); `companion sim --all` at 1 ms and 10 ms from
# the paper's starts (nominal-<dt>.json) and from 24 starts nearby (start-<k>-<dt>.json:
# the target's initial x and q₁(0) offset by k·10⁻⁴ m and rad, k = ±1…±12); T2 (d) with the
# Ψ̇ term at 1 ms from the same 24 starts (psi.json). The sampled law's T2 (d) with the Ψ̇
# term from the same starts goes to OUT/sampled/psi.json.
set -euo pipefail
out=${1:?usage: measure.sh OUT [VARIANT...]}
shift
mkdir -p "$out"
out=$(cd "$out" && pwd)
cd "$(dirname "$0")/../../.."
cargo build --release --quiet -p companion-runtime --bin companion
cargo build --release --quiet -p companion-tests --example alpha_probe
target=${CARGO_TARGET_DIR:-$PWD/target}
bin=$target/release/companion
probe=$target/release/examples/alpha_probe

# name: environment (README.md describes each).
declare -A env=(
  [today]="LAW_VARIANT=0"
  [reordered]="LAW_VARIANT=19 LAW_PARAM=0"
  [exact]="LAW_VARIANT=11"
  [exact-car-too]="LAW_VARIANT=1"
  [half]="LAW_VARIANT=12"
  [exact-decaying]="LAW_VARIANT=14"
  [exact-growing]="LAW_VARIANT=15"
  [exact-rate-only]="LAW_VARIANT=16"
  [exact-v-omega-only]="LAW_VARIANT=18"
  [blend-0.05]="LAW_VARIANT=13 LAW_PARAM=0.05"
  [blend-0.1]="LAW_VARIANT=13 LAW_PARAM=0.1"
  [blend-0.2]="LAW_VARIANT=13 LAW_PARAM=0.2"
)
order=(today reordered exact exact-car-too half exact-decaying exact-growing exact-rate-only
  exact-v-omega-only blend-0.05 blend-0.1 blend-0.2)
[ $# -gt 0 ] && order=("$@")

# `companion sim --all` into a scratch folder; its summaries as one JSON list.
all() { # FILE DT ENV...  (kept if it exists: a run can be resumed)
  local file=$1 dt=$2 tmp
  shift 2
  [ -s "$file" ] && return
  tmp=$(mktemp -d)
  env "$@" "$bin" sim --all --dt "$dt" --no-plots --log-every 1000000 --out "$tmp" >/dev/null
  summaries "$tmp" >"$file.part" && mv "$file.part" "$file"
  rm -rf "$tmp"
}
summaries() {
  python3 - "$1" <<'PY'
import json, os, sys
d = sys.argv[1]
keys = ("fraction_ep_below_1e-3_after_20s", "final_ep_norm", "max_ep_norm_after_20s",
        "v_sign_changes", "max_abs_v", "steps_after_20s")
pick = lambda p: {k: v for k, v in json.load(open(p)).items() if k in keys}
if os.path.exists(os.path.join(d, "summary.json")):  # one run
    print(json.dumps(pick(os.path.join(d, "summary.json"))))
else:  # --all: one folder per run
    rows = {r: pick(os.path.join(d, r, "summary.json")) for r in sorted(os.listdir(d))
            if os.path.exists(os.path.join(d, r, "summary.json"))}
    print(json.dumps(rows))
PY
}
psi() { # FILE ENV... [-- SIM FLAGS...]  (kept if it exists)
  local file=$1 k e tmp
  [ -s "$file" ] && return
  shift
  local envs=() flags=()
  while [ $# -gt 0 ] && [ "$1" != -- ]; do envs+=("$1"); shift; done
  [ $# -gt 0 ] && shift && flags=("$@")
  echo "{" >"$file.part"
  for k in $(seq -12 12); do
    [ "$k" = 0 ] && continue
    e=$(python3 -c "print($k * 1e-4)")
    tmp=$(mktemp -d)
    env "${envs[@]}" LAW_IC="$e" "$bin" sim --trajectory 2 --choice d --psi-rate-in-drift \
      --dt 0.001 --duration 120 --no-plots --log-every 1000000 "${flags[@]}" --out "$tmp" >/dev/null
    printf '"%s": %s,\n' "$k" "$(summaries "$tmp")" >>"$file.part"
    rm -rf "$tmp"
  done
  sed -i '$ s/,$//' "$file.part"
  echo "}" >>"$file.part"
  mv "$file.part" "$file"
}

mkdir -p "$out/sampled"
psi "$out/sampled/psi.json" LAW_VARIANT=0 -- --discretisation sampled
for name in "${order[@]}"; do
  read -r -a e <<<"${env[$name]}"
  dir=$out/$name
  mkdir -p "$dir"
  echo "== $name (${env[$name]})" >&2
  [ -s "$dir/pointwise.txt" ] || (cd "$out" && env "${e[@]}" "$probe" pw) >"$dir/pointwise.txt"
  for dt in 0.001 0.01; do
    all "$dir/nominal-$dt.json" "$dt" "${e[@]}"
    for k in $(seq -12 12); do
      [ "$k" = 0 ] && continue
      all "$dir/start-$k-$dt.json" "$dt" "${e[@]}" LAW_IC="$(python3 -c "print($k * 1e-4)")"
    done
  done
  psi "$dir/psi.json" "${e[@]}"
done
