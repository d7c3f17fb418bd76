#!/usr/bin/env python3
"""An uneven LJ system as a LAMMPS data file (atom style atomic): an fcc
crystal of NX x NY x NZ unit cells at reduced density RHO filling the lower
1/STRETCH of a periodic box that is STRETCH times longer along x (vacuum
above it), the test case of balanced cuts (docs/scaling.md, "Balanced cuts").

    python3 scripts/lj-slab-data.py --cells 20 20 20 --stretch 3 > slab.data

Then a scenario with `[system] read_data = "slab.data"` (and a velocity
table to heat it) runs it.
"""
import argparse

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument("--cells", type=int, nargs=3, required=True, metavar=("NX", "NY", "NZ"))
p.add_argument("--density", type=float, default=0.8442)
p.add_argument("--stretch", type=float, default=3.0)
args = p.parse_args()
if args.stretch < 1.0 or args.density <= 0.0 or min(args.cells) < 1:
    p.error("--stretch must be >= 1, --density > 0 and every cell count >= 1")

a = (4.0 / args.density) ** (1.0 / 3.0)
nx, ny, nz = args.cells
basis = [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.5, 0.0, 0.5), (0.0, 0.5, 0.5)]
# a quarter of a lattice spacing up, so that no atom sits on the box's face
atoms = [
    ((i + bx + 0.25) * a, (j + by) * a, (k + bz) * a)
    for k in range(nz)
    for j in range(ny)
    for i in range(nx)
    for bx, by, bz in basis
]
lines = [
    "LAMMPS data file: fcc slab of %d x %d x %d cells in a box %g times longer along x"
    % (nx, ny, nz, args.stretch),
    "",
    "%d atoms" % len(atoms),
    "1 atom types",
    "",
    "0 %.10f xlo xhi" % (args.stretch * nx * a),
    "0 %.10f ylo yhi" % (ny * a),
    "0 %.10f zlo zhi" % (nz * a),
    "",
    "Masses",
    "",
    "1 1.0",
    "",
    "Atoms # atomic",
    "",
]
lines += ["%d 1 %.10f %.10f %.10f" % (n + 1, x, y, z) for n, (x, y, z) in enumerate(atoms)]
print("\n".join(lines))
