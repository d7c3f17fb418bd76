#!/usr/bin/env bash
# Every `cellist bench` workload on this build against another binary, in one
# run: each round runs every case with the baseline, then with this build.
#
#   BASELINE=/path/to/older/cellist bash scripts/bench-compare.sh     # 3 rounds
#   ROUNDS=5 BASELINE=... bash scripts/bench-compare.sh
#
# Prints one line per run, `round build case seconds`, then per case the
# medians and their ratio (this build over the baseline; below 1 is faster),
# and for the cases run on 1 and 2 threads each build's speed-up on 2.
# The seconds are each bench's own figure: `seconds` (neighbors, billiards),
# `loop_seconds` (lj), `seconds_per_step` (pse), `seconds_per_force`
# (gravity), `seconds_per_velocity` (vortex).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
: "${BASELINE:?set BASELINE to the cellist binary to compare with}"
ROUNDS=${ROUNDS:-3}
cargo build --release -q --manifest-path "$here/Cargo.toml"
current="$here/target/release/cellist"
data="$here/../shared/testdata/billiards/inputs/standard"
log=$(mktemp)
generated=$(mktemp -d)
trap 'rm -rf "$log" "$generated"' EXIT
"$current" billiards gen 100000 20000 30 100 2 5 --overlaps --seed 1 \
    --output "$generated/gen100k.in" > /dev/null
cases=(
    "neighbors-3d-1t|neighbors --n 1000000 --repeat 3 --threads 1"
    "neighbors-3d-2t|neighbors --n 1000000 --repeat 3 --threads 2"
    "neighbors-2d-1t|neighbors --n 1000000 --dim 2 --repeat 3 --threads 1"
    "lj-1t|lj --steps 100 --repeat 3 --threads 1"
    "lj-2t|lj --steps 100 --repeat 3 --threads 2"
    "billiards-0.9-1t|billiards $data/10k_density_0.9.in --repeat 3 --threads 1"
    "billiards-0.9-2t|billiards $data/10k_density_0.9.in --repeat 3 --threads 2"
    "billiards-gen100k-1t|billiards $generated/gen100k.in --repeat 3 --threads 1"
    "billiards-gen100k-2t|billiards $generated/gen100k.in --repeat 3 --threads 2"
    "pse-2d-1t|pse --n-per-side 1000 --dim 2 --method cell-list --threads 1"
    "pse-2d-2t|pse --n-per-side 1000 --dim 2 --method cell-list --threads 2"
    "pse-3d-1t|pse --n-per-side 100 --dim 3 --method cell-list --threads 1"
    "gravity-direct|gravity --solver direct --n 20000 --repeat 3"
    "gravity-bh|gravity --solver barnes-hut --n 100000 --theta 0.5 --repeat 1"
    "vortex-direct|vortex --solver direct --n 20000 --threads 1 --repeat 3"
    "vortex-bh|vortex --solver barnes-hut --n 100000 --threads 1 --repeat 3"
)
seconds() {
    python3 -c 'import json,sys
r = json.load(sys.stdin)
for k in ("seconds", "loop_seconds", "seconds_per_step", "seconds_per_force", "seconds_per_velocity"):
    if k in r:
        print(r[k]); break'
}
for round in $(seq "$ROUNDS"); do
    for case in "${cases[@]}"; do
        name=${case%%|*}
        read -r -a args <<< "${case#*|}"
        for build in baseline current; do
            binary=$BASELINE
            [ "$build" = current ] && binary=$current
            s=$("$binary" bench "${args[@]}" --json | seconds)
            echo "$round $build $name $s" | tee -a "$log"
        done
    done
done
python3 - "$log" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    _, build, name, s = line.split()
    runs.setdefault(name, {}).setdefault(build, []).append(float(s))
print("case baseline_median current_median ratio")
for name, r in runs.items():
    b, c = statistics.median(r["baseline"]), statistics.median(r["current"])
    print(f"{name} {b:.4f} {c:.4f} {c / b:.3f}")
print("case speed-up_2_threads baseline current")
for name in runs:
    if name.endswith("-1t") and name[:-3] + "-2t" in runs:
        one, two = runs[name], runs[name[:-3] + "-2t"]
        up = [statistics.median(one[b]) / statistics.median(two[b]) for b in ("baseline", "current")]
        print(f"{name[:-3]} {up[0]:.2f} {up[1]:.2f}")
PY
