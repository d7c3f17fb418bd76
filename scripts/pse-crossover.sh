#!/usr/bin/env bash
# O(N^2) against O(N): time per forward Euler step of the all-pairs sum and of the
# cell list (cutoff 5 eps, eps = h), 2D lattices, 1 thread; medians of 3.
#   bash scripts/pse-crossover.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
printf '%6s %9s %14s %14s %8s\n' "n" "N" "direct (s)" "cell list (s)" "ratio"
for n in 12 16 24 32 48 64 96 128; do
  d=$(./target/release/cellist bench pse --n-per-side $n --method direct --steps 3 --repeat 3 --json)
  c=$(./target/release/cellist bench pse --n-per-side $n --method cell-list --steps 3 --repeat 3 --json)
  python3 -c "
import json
d, c = json.loads('$d'), json.loads('$c')
print(f\"{$n:6} {d['particles']:9} {d['seconds_per_step']:14.4e} {c['seconds_per_step']:14.4e} {d['seconds_per_step'] / c['seconds_per_step']:8.2f}\")"
done
