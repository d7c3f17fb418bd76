"""Shared helpers of the Python tests: the `cellist` command line (built by
`cargo build --release`, or named by $CELLIST_BIN) and small scenarios."""

import os
import pathlib
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def cellist_binary():
    named = os.environ.get("CELLIST_BIN")
    if named:
        return pathlib.Path(named)
    built = ROOT / "target" / "release" / "cellist"
    if built.exists():
        return built
    found = shutil.which("cellist")
    if found:
        return pathlib.Path(found)
    pytest.fail("the cellist command line is not built: run `cargo build --release` first "
                "(or set CELLIST_BIN)")


@pytest.fixture
def cli():
    """Runs `cellist ARGS...` and returns its standard output."""
    binary = cellist_binary()

    def run(*args, cwd=None):
        done = subprocess.run([str(binary), *map(str, args)], cwd=cwd, capture_output=True,
                              text=True)
        assert done.returncode == 0, done.stderr
        return done.stdout

    return run


MD_SMALL = """
model = "md"
dimension = 3

[system]
lattice = {{ kind = "fcc", density = 0.8442, cells = [4, 4, 4] }}
velocity = {{ temperature = 3.0, seed = 87287 }}

[pair]
cutoff = 2.5
shift = true

[run]
steps = {steps}
dt = 0.005

[output]
thermo_every = 10
dump = {{ every = {steps}, file = "final.lammpstrj", columns = ["id", "type", "x", "y", "z", "vx", "vy", "vz"] }}
"""


def md_scenario(steps=40):
    """A 256-atom LJ melt whose dump holds the last step's positions and velocities."""
    return MD_SMALL.format(steps=steps)


def read_dump_last_frame(path):
    """The columns of the last frame of a LAMMPS dump, as a dict of float lists."""
    lines = pathlib.Path(path).read_text().splitlines()
    start = max(k for k, line in enumerate(lines) if line.startswith("ITEM: TIMESTEP"))
    count = int(lines[start + 3])
    header = lines[start + 8].split()[2:]
    rows = [line.split() for line in lines[start + 9:start + 9 + count]]
    return {name: [float(r[k]) for r in rows] for k, name in enumerate(header)}
