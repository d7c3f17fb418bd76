#!/usr/bin/env bash
# The validation runs of the 3D vortex particle method (docs/models.md, "vortex
# in 3D"): a thin ring's speed against the Fraenkel-Saffman formula by solver
# and spacing, the ABC flow's vorticity error by spacing (inviscid and viscous),
# and the invariants of a ring travelling two diameters.
#   bash scripts/vortex3-validation.sh [ring|abc|travel|effects ...]   (default: all)
# Results in out/vortex3-validation/; the tables are printed.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
C=./target/release/cellist
OUT=out/vortex3-validation
mkdir -p "$OUT"
CASES=${*:-ring abc travel effects}

last() { tail -1 "$1" | tr ',' ' '; }
col() { head -1 "$1" | tr ',' '\n' | grep -nx "$2" | cut -d: -f1; }

for case in $CASES; do
case $case in
ring)
    # R = 1, G = 1, core s = 0.1 (s/R = 0.1); speed = slope of ring_z over 0.2 time units
    echo "solver spacing particles speed thin_ring_speed relative_difference"
    for solver in mesh barnes-hut direct; do
        for cores in 2 2.5 3; do
            if [ "$solver" = direct ] && [ "$cores" != 2 ]; then continue; fi
            h=$(python3 -c "print(0.1 / $cores)")
            case $solver in
                mesh) v='{ kind = "mesh", grid = 128 }' ;;
                barnes-hut) v='{ kind = "barnes-hut" }' ;;
                direct) v='{ kind = "direct" }' ;;
            esac
            dir="$OUT/ring-$solver-$cores"
            cat > "$OUT/ring.toml" <<TOML
model = "vortex"
dimension = 3
[system]
initial = { kind = "ring", radius = 1.0, circulation = 1.0, core = 0.1, spacing = $h }
velocity = $v
[run]
steps = 10
dt = 0.02
integrator = "rk2"
[output]
thermo_every = 10
png = { every = 0 }
gif = { every = 0 }
TOML
            $C run "$OUT/ring.toml" --out "$dir" > "$dir.log" 2>&1
            python3 - "$dir/thermo.csv" "$solver" "$h" <<'PY'
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
h = float(sys.argv[3])
speed = (float(rows[-1]["ring_z"]) - float(rows[0]["ring_z"])) / float(rows[-1]["time"])
s, sigma = 0.1, 1.5 * h
se = math.sqrt(s * s + 2 * sigma * sigma)
u = 1 / (4 * math.pi) * (math.log(8 / se) - 0.558)
n = open(sys.argv[1].replace("thermo.csv", "summary.json")).read()
import json
particles = json.loads(n)["particles"]
print(f"{sys.argv[2]} {h:.5f} {particles} {speed:.5f} {u:.5f} {(speed - u) / u:+.4f}")
PY
        done
    done
    ;;
abc)
    # A = B = C = 1 on the periodic mesh (grid = n), 1 time unit
    echo "nu n spacing l2_error max_error"
    for nu in 0 0.05; do
        for n in 16 32 64; do
            h=$(python3 -c "import math; print(2 * math.pi / $n)")
            dt=$(python3 -c "print(1.6 / $n)")
            steps=$((n * 10 / 16))
            dir="$OUT/abc-$nu-$n"
            cat > "$OUT/abc.toml" <<TOML
model = "vortex"
dimension = 3
[system]
initial = { kind = "abc", spacing = $h }
nu = $nu
velocity = { kind = "mesh", boundary = "periodic", box = 6.283185307179586, grid = $n }
[run]
steps = $steps
dt = $dt
integrator = "rk4"
[output]
thermo_every = $steps
png = { every = 0 }
gif = { every = 0 }
TOML
            $C run "$OUT/abc.toml" --out "$dir" > "$dir.log" 2>&1
            f="$dir/thermo.csv"
            echo "$nu $n $h $(last "$f" | awk -v a="$(col "$f" omega_l2_error)" -v b="$(col "$f" omega_max_error)" '{print $a, $b}')"
        done
    done
    ;;
travel)
    # the ring of examples/vortex-ring.toml (core 0.2, spacing 0.1) over 20 time
    # units (about two diameters), remeshed, inviscid
    dir="$OUT/travel"
    $C run examples/vortex-ring.toml --out "$dir" --set run.steps=400 --set output.thermo_every=20 \
        --set 'output.gif={every=0}' --set 'output.field={every=0}' > "$dir.log" 2>&1
    python3 - "$dir/thermo.csv" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
first, last = rows[0], rows[-1]
iz0 = float(first["impulse_z"])
print("time ring_z impulse_z relative_impulse_change energy relative_energy_change total_vorticity")
for r in rows[:: max(1, len(rows) // 5)] + [last]:
    print(r["time"], r["ring_z"], r["impulse_z"], f"{(float(r['impulse_z']) - iz0) / iz0:+.2e}",
          r["energy"], f"{(float(r['energy']) - float(first['energy'])) / float(first['energy']):+.2e}",
          max(abs(float(r[k])) for k in ("total_vorticity_x", "total_vorticity_y", "total_vorticity_z")))
PY
    ;;
effects)
    # the ring of examples/vortex-ring.toml over 3 time units: what remeshing,
    # the relaxation and viscosity each change
    echo "variant particles speed impulse_z_change enstrophy_change max_total_vorticity"
    for variant in base no-remeshing relaxation viscous classical; do
        sets=(--set run.steps=60 --set output.thermo_every=10 --set 'output.gif={every=0}' --set 'output.field={every=0}')
        case $variant in
            no-remeshing) sets+=(--set system.remesh_every=0) ;;
            relaxation) sets+=(--set 'system.relaxation={factor=0.3,every=5}') ;;
            viscous) sets+=(--set system.nu=0.005) ;;
            classical) sets+=(--set 'system.stretching="classical"') ;;
        esac
        dir="$OUT/effects-$variant"
        $C run examples/vortex-ring.toml --out "$dir" "${sets[@]}" > "$dir.log" 2>&1
        python3 - "$dir" "$variant" <<'PY'
import csv, json, sys
rows = list(csv.DictReader(open(sys.argv[1] + "/thermo.csv")))
a, b = rows[0], rows[-1]
f = lambda r, k: float(r[k])
speed = (f(b, "ring_z") - f(a, "ring_z")) / f(b, "time")
particles = json.load(open(sys.argv[1] + "/summary.json"))["particles"]
total = max(abs(f(b, k)) for k in ("total_vorticity_x", "total_vorticity_y", "total_vorticity_z"))
print(sys.argv[2], particles, f"{speed:.5f}", f"{(f(b, 'impulse_z') - f(a, 'impulse_z')) / f(a, 'impulse_z'):+.2e}",
      f"{(f(b, 'enstrophy') - f(a, 'enstrophy')) / f(a, 'enstrophy'):+.2e}", f"{total:.1e}")
PY
    done
    ;;
esac
done
