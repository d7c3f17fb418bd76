#!/usr/bin/env bash
# cellist's FMM against the Flatiron Institute's FMM2D (`fmm2dpy.cfmm2d`, the
# package index's build) on the same points and circulations, one thread each
# (OMP_NUM_THREADS=1, --threads 1), both errors measured against a direct sum on
# sampled targets (RMS relative: sqrt(sum |e|^2 / sum |u|^2)).
#
#   bash scripts/fmm-vs-peers.sh                 # 2D, 10^6 uniform points, 3 rounds
#   N=100000 ROUNDS=5 EPS=1e-8 bash scripts/fmm-vs-peers.sh
#
# Each round runs FMM2D at eps = EPS, then cellist at --tolerance EPS and at
# --tolerance EPS/100 (about FMM2D's measured error, which its conservative eps
# puts far below EPS), alternating; the medians and ratios are printed at the
# end. The points are uniform in the unit square with circulations uniform in
# [-0.5, 0.5] (lines `x y gamma`), written by the peer's own numpy; FMM2D comes
# from ../shared/peers/fmm/run.sh (installed into its venv on first use).
# The 3D part of issue 45 (FMM3D's lfmm3d against a 3D Laplace FMM) is not
# built yet: cellist has no 3D FMM.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
peer="$here/../shared/peers/fmm/run.sh"
VENV=${FMM_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/fmm-venv}
N=${N:-1000000}
ROUNDS=${ROUNDS:-3}
EPS=${EPS:-1e-6}
[ -x "$VENV/bin/python" ] || FMM_VENV="$VENV" bash "$peer" install
cargo build --release --quiet --manifest-path "$here/Cargo.toml" -p cellist-cli
cellist="${CARGO_TARGET_DIR:-$here/target}/release/cellist"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
points="$work/points-$N.txt"
"$VENV/bin/python" - "$N" "$points" <<'EOF'
import sys
import numpy as np
n, path = int(sys.argv[1]), sys.argv[2]
rng = np.random.default_rng(45)
np.savetxt(path, np.column_stack([rng.random(n), rng.random(n), rng.random(n) - 0.5]), fmt="%.17g")
EOF
tight=$(python3 -c "print(f'{$EPS / 100:g}')")
: > "$work/lines"
for round in $(seq "$ROUNDS"); do
    # the Fortran library prints progress lines beside the JSON
    FMM_VENV="$VENV" bash "$peer" bench 2d "$points" "$EPS" | grep '^{' \
        | python3 -c 'import json,sys; d=json.load(sys.stdin); print("fmm2d", d["seconds"], d["rms_relative_error"])' \
        | tee -a "$work/lines"
    for tolerance in "$EPS" "$tight"; do
        "$cellist" bench vortex --solver fmm --tolerance "$tolerance" --input "$points" \
            --threads 1 --repeat 1 --sample 1000 --json \
            | python3 -c 'import json,sys; d=json.load(sys.stdin); print("cellist-'"$tolerance"'", d["seconds_per_velocity"], d["rms_relative_velocity_error"])' \
            | tee -a "$work/lines"
    done
done
python3 - "$work/lines" "$N" "$EPS" <<'EOF'
import statistics, sys
rows = [line.split() for line in open(sys.argv[1])]
codes = list(dict.fromkeys(r[0] for r in rows))
med = {c: (statistics.median(float(r[1]) for r in rows if r[0] == c),
           statistics.median(float(r[2]) for r in rows if r[0] == c)) for c in codes}
print(f"\n{sys.argv[2]} uniform points, eps {sys.argv[3]}, medians of {len(rows) // len(codes)} rounds:")
print(f"{'code':>22} {'seconds':>9} {'RMS error':>10} {'time / fmm2d':>13}")
for c in codes:
    s, e = med[c]
    print(f"{c:>22} {s:9.3f} {e:10.2e} {s / med['fmm2d'][0]:13.3f}")
EOF
