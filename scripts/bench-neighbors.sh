#!/usr/bin/env bash
# cellist's neighbour-list benchmark side by side with its peers, in one run.
#
#   bash scripts/bench-neighbors.sh            # 1M points, 3D and 2D, 1 and 2 threads
#   REPEAT=5 bash scripts/bench-neighbors.sh
#
# Needs the peers' virtual environment: bash ../shared/peers/neighbors/run.sh installs
# it (vesin, scipy, ...), or VENV=/path/to/venv with `pip install vesin scipy numpy`.
# Each case is one process; cellist and the peers alternate so that they share the
# machine's state. Prints one JSON line per measurement.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
peers="$here/../shared/peers/neighbors"
VENV=${VENV:-${TMPDIR:-/tmp}/nbpeers-venv}
REPEAT=${REPEAT:-3}
export BENCH_LOCK=${BENCH_LOCK:-${TMPDIR:-/tmp}/cellist-bench.lock}
cargo build --release --quiet --manifest-path "$here/Cargo.toml"
cellist="$here/target/release/cellist"

peer() {  # lib n dim threads
    OMP_NUM_THREADS=$4 flock "$BENCH_LOCK" "$VENV/bin/python" "$peers/bench.py" run \
        --lib "$1" --n "$2" --dim "$3" --threads "$4" --repeats "$REPEAT" \
        | python3 -c 'import json,sys; r=json.loads(sys.stdin.read().strip().splitlines()[-1]);
print(json.dumps({k: r[k] for k in ("lib","n","dim","threads","median_s","unique_pairs","ns_per_pair")}))'
}
ours() {  # n dim threads
    flock "$BENCH_LOCK" "$cellist" bench neighbors --n "$1" --dim "$2" --threads "$3" --repeat "$REPEAT" --json
}

for threads in 1 2; do
    peer vesin 1000000 3 "$threads"
    ours 1000000 3 "$threads"
    peer vesin 1000000 2 "$threads"
    ours 1000000 2 "$threads"
done
peer scipy-cKDTree.query_pairs 1000000 2 1
ours 1000000 2 1
