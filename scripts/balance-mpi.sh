#!/usr/bin/env bash
# Balanced against equal cut planes (`[decomposition] balance = "rcb"` or
# "uniform") on 2 MPI ranks, one thread per rank: the loop seconds and the
# load imbalances of each run's summary.json, medians of alternating rounds.
#
#   bash scripts/balance-mpi.sh                 # 3 alternating rounds
#   ROUNDS=5 STEPS=200 RANKS=4 bash scripts/balance-mpi.sh
#
# Cases (LJ, cutoff 2.5, T = 3, `STEPS` steps):
#   slab:  32000 atoms, an fcc slab of 20^3 cells filling the lower third of a
#          box three times longer along x (scripts/lj-slab-data.py)
#   melt:  32000 atoms, fcc 20^3 filling its box (an even system)
# Needs Open MPI; builds cellist with --features mpi (in CARGO_TARGET_DIR if
# set). Prints `case balance loop_seconds imbalance_particles imbalance_busy`
# per run, then the medians.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
ROUNDS=${ROUNDS:-3}
STEPS=${STEPS:-100}
RANKS=${RANKS:-2}
LOCK=${BENCH_LOCK:-${TMPDIR:-/tmp}/cellist-bench.lock}
cargo build --release --quiet -p cellist-cli --features mpi --manifest-path "$here/Cargo.toml"
cellist="${CARGO_TARGET_DIR:-$here/target}/release/cellist"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 "$here/scripts/lj-slab-data.py" --cells 20 20 20 --stretch 3 > "$work/slab.data"

scenario() {  # file system-lines
    cat > "$1" <<EOF
model = "md"
[system]
$2
velocity = { temperature = 3.0, seed = 87287 }
[pair]
cutoff = 2.5
[run]
steps = $STEPS
[output]
thermo_every = $STEPS
EOF
}
scenario "$work/slab.toml" 'read_data = "slab.data"'
scenario "$work/melt.toml" 'lattice = { kind = "fcc", density = 0.8442, cells = [20, 20, 20] }'

run() {  # case balance
    local out="$work/out-$1-$2"
    flock "$LOCK" mpirun --allow-run-as-root --oversubscribe -np "$RANKS" "$cellist" run \
        "$work/$1.toml" --threads 1 --out "$out" --set "decomposition.balance=\"$2\"" >/dev/null
    python3 - "$1" "$2" "$out/summary.json" <<'EOF'
import json, sys
s = json.load(open(sys.argv[3]))
print(sys.argv[1], sys.argv[2], s["loop_seconds"], s["imbalance_particles"], s["imbalance_busy"])
EOF
    rm -rf "$out"
}

{
    for r in $(seq 1 "$ROUNDS"); do
        for case in slab melt; do
            run "$case" uniform
            run "$case" rcb
        done
    done
} | tee "$work/runs.txt"
echo "# medians of $ROUNDS rounds on $RANKS ranks ($STEPS steps)"
python3 - "$work/runs.txt" <<'EOF'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    case, balance, *figures = line.split()
    runs.setdefault((case, balance), []).append([float(f) for f in figures])
print("case balance loop_seconds imbalance_particles imbalance_busy")
for (case, balance), rows in runs.items():
    medians = [statistics.median(column) for column in zip(*rows)]
    print(case, balance, " ".join(f"{m:.3f}" for m in medians))
EOF
