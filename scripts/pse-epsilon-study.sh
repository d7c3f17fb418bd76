#!/usr/bin/env bash
# The epsilon experiment of seed 002: the sine mode on a 64 x 64 lattice (h = 1/64),
# RK4 to t = 0.002, for eps from well below to well above the spacing; prints the
# relative L2 error against the exact solution at the end.
#   bash scripts/pse-epsilon-study.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
n=64
printf '%8s %12s %14s %14s\n' "eps/h" "eps" "L2 error" "rel. L2 error"
for ratio in 0.25 0.5 0.75 1 1.5 2 3 4; do
  eps=$(python3 -c "print($ratio / $n)")
  out=out/pse-eps-study/eps-$ratio
  ./target/release/cellist run examples/pse-sine.toml --out "$out" \
    --set system.lattice.n=$n --set system.epsilon="$eps" \
    --set run.steps=100 --set run.dt=2e-5 --set output.thermo_every=100 \
    --set output.field.every=0 --set output.gif.every=0 --set output.png.every=0 >/dev/null 2>&1
  # the exact amplitude at t: exp(-8 pi^2 t); its L2 norm on the unit box is amplitude / 2
  tail -1 "$out/thermo.csv" | python3 -c "
import sys, math
step, t, total, l2, mx = map(float, sys.stdin.read().split(','))
norm = math.exp(-8 * math.pi**2 * t) / 2
print(f'{$ratio:8} {$eps:12.6g} {l2:14.4e} {l2 / norm:14.4e}')"
done
