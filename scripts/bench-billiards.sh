#!/usr/bin/env bash
# The hard-disk collision benchmark of issue 4: the three standard inputs and a
# generated 100000-disc case, on 1 and 2 threads, several rounds.
#
#   bash scripts/bench-billiards.sh                      # 3 rounds
#   BASELINE=/path/to/older/cellist bash scripts/bench-billiards.sh
#
# BASELINE (optional) is another cellist binary, timed on 10k_density_0.9 right
# after this build in every round, so that the two see the same machine state.
# The 100000-disc input is made once in out/ by `cellist billiards gen`.
# Prints one line per run: `round build threads input seconds sweeps`, seconds
# being the median of `--repeat 3`.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
data="$here/../shared/testdata/billiards/inputs/standard"
ROUNDS=${ROUNDS:-3}
cargo build --release -q --manifest-path "$here/Cargo.toml"
cellist="$here/target/release/cellist"
mkdir -p "$here/out"
large="$here/out/large100k.in"
[ -f "$large" ] || "$cellist" billiards gen 100000 20000 30 100 2 5 --overlaps --seed 1 --output "$large"
run() { # build-name binary threads input
    "$2" bench billiards "$4" --threads "$3" --repeat 3 --json |
        python3 -c "import json,sys; d=json.load(sys.stdin); print('$1', $3, '$(basename "$4")', d['seconds'], d['max_sweeps'])"
}
for round in $(seq "$ROUNDS"); do
    for input in "$data/10k_density_0.7.in" "$data/10k_density_0.8.in" "$data/10k_density_0.9.in" "$large"; do
        for threads in 1 2; do
            echo "$round $(run cellist "$cellist" $threads "$input")"
            if [ -n "${BASELINE:-}" ] && [ "$input" = "$data/10k_density_0.9.in" ]; then
                echo "$round $(run baseline "$BASELINE" $threads "$input")"
            fi
        done
    done
done
