#!/usr/bin/env bash
# Seed 004's convergence experiment from the command line: the two-body set-up
# run to t = 15 with h, h/2, h/4 for explicit Euler and leapfrog; the observed order
# is log2(|v_h - v_h/2| / |v_h/2 - v_h/4|) of the largest speed at t = 15.
#   bash scripts/gravity-convergence.sh [h]      (default h = 0.004)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
H="${1:-0.004}"
OUT="${TMPDIR:-/tmp}/cellist-gravity-convergence"
for integrator in euler leapfrog; do
  speeds=()
  for k in 1 2 4; do
    dt=$(python3 -c "print($H / $k)")
    steps=$(python3 -c "print(round(15 / ($H / $k)))")
    dir="$OUT/$integrator-$k"
    ./target/release/cellist run examples/gravity-two-body.toml --out "$dir" \
      --set run.integrator="\"$integrator\"" --set run.dt=$dt --set run.steps=$steps \
      --set "output.dump={ every = $steps, file = \"end.dump\", columns = [\"vx\", \"vy\", \"vz\"] }" > /dev/null
    speeds+=("$(python3 -c "
rows = open('$dir/end.dump').read().split('ITEM: ATOMS vx vy vz')[-1].split()
v = [float(x) for x in rows]
print(max((v[i]**2 + v[i+1]**2 + v[i+2]**2) ** 0.5 for i in range(0, len(v), 3)))")")
  done
  python3 -c "
import math
v = [${speeds[0]}, ${speeds[1]}, ${speeds[2]}]
print(f'$integrator: v(h) = {v[0]:.12f}, v(h/2) = {v[1]:.12f}, v(h/4) = {v[2]:.12f}, observed order {math.log2(abs(v[0]-v[1]) / abs(v[1]-v[2])):.3f}')"
done
