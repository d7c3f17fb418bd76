#!/usr/bin/env python3
"""The Python module's benchmarks, in one run, alternating rounds (medians):

1. cellist.neighbors on 10^6 uniform points in 3D (density 0.8442, cutoff 2.5,
   one thread), sorted (the default) and sorted=False, against `cellist bench
   neighbors` on the same workload, unsorted (u32 pairs as found), --as-found
   (the int64 arrays sorted=False returns) and --sorted (the sorted list the
   module returns by default).
2. Two simulations of one thread each (an LJ melt of 4000 atoms) run one after
   the other, then in two Python threads: the GIL is released if the second
   takes well under the first.

    python3 -m venv .venv && .venv/bin/pip install ./python
    .venv/bin/python scripts/bench-python.py            # ROUNDS=3 by default
"""

import json
import os
import pathlib
import statistics
import subprocess
import tempfile
import threading
import time

import numpy as np

import cellist

ROOT = pathlib.Path(__file__).resolve().parents[1]
CELLIST = os.environ.get("CELLIST_BIN", str(ROOT / "target" / "release" / "cellist"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
N, DENSITY, CUTOFF = 1_000_000, 0.8442, 2.5

MELT = """
model = "md"
[system]
lattice = {{ kind = "fcc", density = 0.8442, cells = [10, 10, 10] }}
velocity = {{ temperature = 3.0, seed = {seed} }}
[pair]
cutoff = 2.5
shift = true
[run]
steps = 400
dt = 0.005
[output]
thermo_every = 400
"""


def bench_cli(*flags):
    out = subprocess.run([CELLIST, "bench", "neighbors", "--n", str(N), "--repeat", "1",
                          "--threads", "1", "--json", *flags],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)["seconds"]


def bench_module(points, side, sorted=True):
    start = time.perf_counter()
    i, j = cellist.neighbors(points, CUTOFF, box=[side] * 3, threads=1, sorted=sorted)
    seconds = time.perf_counter() - start
    del i, j
    return seconds


def one_melt(seed, out):
    with cellist.Simulation.from_toml(MELT.format(seed=seed), threads=1, out=out) as sim:
        sim.run()


def melts(parallel, out):
    start = time.perf_counter()
    if parallel:
        workers = [threading.Thread(target=one_melt, args=(seed, f"{out}/{seed}"))
                   for seed in (1, 2)]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
    else:
        for seed in (1, 2):
            one_melt(seed, f"{out}/{seed}")
    return time.perf_counter() - start


def main():
    side = (N / DENSITY) ** (1 / 3)
    points = np.random.default_rng(20260601).uniform(0.0, side, size=(N, 3))
    times = {"bench": [], "cellist.neighbors(sorted=False)": [], "bench --as-found": [],
             "bench --sorted": [],
             "cellist.neighbors": [],
             "two melts one after the other": [], "two melts in two threads": []}
    with tempfile.TemporaryDirectory() as out:
        for _ in range(ROUNDS):
            times["bench"].append(bench_cli())
            times["cellist.neighbors(sorted=False)"].append(bench_module(points, side, False))
            times["bench --as-found"].append(bench_cli("--as-found"))
            times["cellist.neighbors"].append(bench_module(points, side))
            times["bench --sorted"].append(bench_cli("--sorted"))
            times["two melts one after the other"].append(melts(False, out))
            times["two melts in two threads"].append(melts(True, out))
    medians = {k: statistics.median(v) for k, v in times.items()}
    for k, v in times.items():
        print(f"{k:32s} median {medians[k]:.3f} s  runs {' '.join(f'{t:.3f}' for t in v)}")
    print(f"cellist.neighbors / bench --sorted: {medians['cellist.neighbors'] / medians['bench --sorted']:.2f}")
    print(f"cellist.neighbors / bench:          {medians['cellist.neighbors'] / medians['bench']:.2f}")
    as_found = medians["cellist.neighbors(sorted=False)"] / medians["bench"]
    print(f"cellist.neighbors(sorted=False) / bench: {as_found:.2f}")
    binding = medians["cellist.neighbors(sorted=False)"] / medians["bench --as-found"]
    print(f"cellist.neighbors(sorted=False) / bench --as-found: {binding:.2f}")
    ratio = medians["two melts in two threads"] / medians["two melts one after the other"]
    print(f"two threads / one after the other:  {ratio:.2f}")


if __name__ == "__main__":
    main()
