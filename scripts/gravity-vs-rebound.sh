#!/usr/bin/env bash
# cellist's gravity solvers side by side with REBOUND 5.2.2 in the same run, each
# timing under one lock (../shared/peers/gravity/bench.py is the peer's harness).
#   bash scripts/gravity-vs-rebound.sh            # REBOUND venv in /tmp/rebound-venv
# Prints JSON lines: REBOUND's ("what": ...) and cellist's ("solver": ...).
set -euo pipefail
cd "$(dirname "$0")/.."
PEER=../shared/peers/gravity
VENV="${REBOUND_VENV:-/tmp/rebound-venv}"
LOCK="${BENCH_LOCK:-${TMPDIR:-/tmp}/cellist-bench.lock}"
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install --quiet "rebound==5.2.2" "numpy==2.4.6"
fi
cargo build --release --quiet
L() { flock "$LOCK" "$@"; }
C=./target/release/cellist
PY="$VENV/bin/python $PEER/bench.py"

# direct sum: ns per pair, 1 core
L $PY direct --n 1000 4000 16000
for n in 1000 4000 16000; do L $C bench gravity --solver direct --n $n --repeat 5 --json; done

# Barnes-Hut accuracy and time on 10^4 bodies (REBOUND: monopole tree)
L $PY accuracy --n 10000 --theta 0.3 0.5 0.7 1.0
for theta in 0.3 0.5 0.7 1.0; do
  L $C bench gravity --solver barnes-hut --n 10000 --theta $theta --repeat 5 --json
  L $C bench gravity --solver barnes-hut --n 10000 --theta $theta --monopole --repeat 5 --json
done

# Barnes-Hut on 10^5 bodies: seconds per step (REBOUND) and per force (cellist)
L $PY tree --n 100000 --theta 0.5
for theta in 0.5 0.7 1.0; do
  L $C bench gravity --solver barnes-hut --n 100000 --theta $theta --repeat 5 --json
  L $C bench gravity --solver barnes-hut --n 100000 --theta $theta --repeat 5 --threads 2 --json
done
