#!/usr/bin/env bash
# cellist's FMM against the Flatiron Institute's FMM2D (`fmm2dpy.cfmm2d`) or
# FMM3D (`fmm3dpy.lfmm3d`), the package index's builds, on the same points and
# charges, one thread each (OMP_NUM_THREADS=1, --threads 1), both errors
# measured against a direct sum on 1000 sampled targets (RMS relative:
# sqrt(sum |e|^2 / sum |u|^2), of the velocity in 2D and the field in 3D).
#
#   bash scripts/fmm-vs-peers.sh                 # 2D, 10^6 uniform points, 3 rounds
#   DIM=3 bash scripts/fmm-vs-peers.sh           # 3D: gravity's 1/r (--softening 0)
#   N=100000 ROUNDS=5 EPS=1e-8 bash scripts/fmm-vs-peers.sh
#
# Each round runs the peer at eps = EPS, then cellist at --tolerance EPS and at
# --tolerance EPS/100 (3D: EPS/4; about the peer's measured error, which its
# conservative eps puts far below EPS), alternating; the medians and ratios are printed at
# the end. The points are uniform in the unit square (cube) with circulations
# uniform in [-0.5, 0.5] (masses uniform in [0, 1)), lines `x y gamma`
# (`x y z m`), written by the peer's own numpy; the peers come from
# ../shared/peers/fmm/run.sh (installed into its venv on first use).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
peer="$here/../shared/peers/fmm/run.sh"
VENV=${FMM_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/fmm-venv}
N=${N:-1000000}
ROUNDS=${ROUNDS:-3}
EPS=${EPS:-1e-6}
DIM=${DIM:-2}
[ -x "$VENV/bin/python" ] || FMM_VENV="$VENV" bash "$peer" install
cargo build --release --quiet --manifest-path "$here/Cargo.toml" -p cellist-cli
cellist="${CARGO_TARGET_DIR:-$here/target}/release/cellist"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
points="$work/points-$N.txt"
"$VENV/bin/python" - "$N" "$points" "$DIM" <<'EOF'
import sys
import numpy as np
n, path, dim = int(sys.argv[1]), sys.argv[2], sys.argv[3]
rng = np.random.default_rng(45)
if dim == "3":
    columns = [rng.random(n), rng.random(n), rng.random(n), rng.random(n)]
else:
    columns = [rng.random(n), rng.random(n), rng.random(n) - 0.5]
np.savetxt(path, np.column_stack(columns), fmt="%.17g")
EOF
# one cellist evaluation at tolerance $1: "seconds error"
case "$DIM" in
    2) peer_name=fmm2d
       cellist_bench() {
           "$cellist" bench vortex --solver fmm --tolerance "$1" --input "$points" \
               --threads 1 --repeat 1 --sample 1000 --json \
               | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["seconds_per_velocity"], d["rms_relative_velocity_error"])'
       } ;;
    3) peer_name=fmm3d
       cellist_bench() {
           "$cellist" bench gravity --solver fmm --tolerance "$1" --input "$points" \
               --softening 0 --threads 1 --repeat 1 --sample 1000 --json \
               | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["seconds_per_force"], d["rms_field_error"])'
       } ;;
    *) echo "DIM must be 2 or 3, got $DIM" >&2; exit 2 ;;
esac
# the tighter tolerance: about the peer's measured error (2D: EPS/100; 3D,
# whose fit is more conservative: EPS/4, order 16 at 1e-6)
tight=$(python3 -c "print(f'{$EPS / (100 if $DIM == 2 else 4):g}')")
: > "$work/lines"
for round in $(seq "$ROUNDS"); do
    # the Fortran library prints progress lines beside the JSON
    FMM_VENV="$VENV" bash "$peer" bench "${DIM}d" "$points" "$EPS" | grep '^{' \
        | python3 -c 'import json,sys; d=json.load(sys.stdin); print(sys.argv[1], d["seconds"], d["rms_relative_error"])' "$peer_name" \
        | tee -a "$work/lines"
    for tolerance in "$EPS" "$tight"; do
        echo "cellist-$tolerance $(cellist_bench "$tolerance")" | tee -a "$work/lines"
    done
done
python3 - "$work/lines" "$N" "$EPS" "$peer_name" <<'EOF'
import statistics, sys
rows = [line.split() for line in open(sys.argv[1])]
codes = list(dict.fromkeys(r[0] for r in rows))
med = {c: (statistics.median(float(r[1]) for r in rows if r[0] == c),
           statistics.median(float(r[2]) for r in rows if r[0] == c)) for c in codes}
print(f"\n{sys.argv[2]} uniform points, eps {sys.argv[3]}, medians of {len(rows) // len(codes)} rounds:")
peer = sys.argv[4]
print(f"{'code':>22} {'seconds':>9} {'RMS error':>10} {'time / ' + peer:>13}")
for c in codes:
    s, e = med[c]
    print(f"{c:>22} {s:9.3f} {e:10.2e} {s / med[peer][0]:13.3f}")
EOF
