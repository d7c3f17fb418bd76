#!/usr/bin/env python3
"""Seed 003's cost model of a distributed step, t = t_comp + t_comm with
t_comm = alpha + beta * bytes per message, for cellist's domain-decomposed LJ
melt at 10^9 atoms on 1, 10 and 1000 nodes, and the condition under which the
ring pass of the direct gravity hides its communication.

    python3 scripts/mpi-cost-model.py --compute-us 0.74 --ghost-ratio 1.6 \
        --ghost-atoms 15500

The measured inputs (docs/scaling.md says where each comes from):
  --compute-us   seconds per atom-step of one rank on one core, in microseconds,
                 of the distributed code (its own atoms' forces, each pair
                 computed on both sides, neighbour-list builds, integration)
  --ghost-atoms  ghosts a rank held in the measured run ...
  --own-atoms    ... for this many own atoms (calibrates the ghost shell)
  --pair-ns      nanoseconds per one-sided gravity pair in the ring
The stated machine: nodes of --cores cores (one rank per core), a network of
latency --alpha-us and bandwidth --gbytes-per-s per node, --memory-gb per node.
"""
import argparse
import math

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument("--compute-us", type=float, required=True)
p.add_argument("--ghost-atoms", type=float, required=True)
p.add_argument("--own-atoms", type=float, required=True)
p.add_argument("--pair-ns", type=float, required=True)
p.add_argument("--bytes-per-atom", type=float, default=800.0,
               help="resident memory per atom of a run (default 800 B, docs/benchmarks.md)")
p.add_argument("--atoms", type=float, default=1e9)
p.add_argument("--cores", type=int, default=64)
p.add_argument("--alpha-us", type=float, default=1.5)
p.add_argument("--gbytes-per-s", type=float, default=12.5)
p.add_argument("--memory-gb", type=float, default=256.0)
p.add_argument("--rebuild-every", type=float, default=5.0,
               help="steps between neighbour-list rebuilds (migration + new ghost plan)")
a = p.parse_args()

density, reach = 0.8442, 2.8  # the melt's density and cutoff + skin (sigma)
alpha = a.alpha_us * 1e-6
beta = 1.0 / (a.gbytes_per_s * 1e9)  # seconds per byte through one node's link


def shell(n):
    """Ghosts of a cubic subdomain of n atoms: the atoms within `reach` of it."""
    side = (n / density) ** (1.0 / 3.0)
    return density * ((side + 2 * reach) ** 3 - side ** 3)


# calibrate the geometric shell on the measured run (its subdomains are not cubes)
calibration = a.ghost_atoms / shell(a.own_atoms)

print(f"# cost per step of {a.atoms:.0e} LJ atoms (fcc melt, rho {density}, cutoff + skin {reach})")
print(f"# measured: {a.compute_us} us per atom-step per core; {a.ghost_atoms:.0f} ghosts for "
      f"{a.own_atoms:.0f} own atoms (shell calibration {calibration:.2f})")
print(f"# stated: {a.cores} cores per node, alpha {a.alpha_us} us, {a.gbytes_per_s} GB/s per node, "
      f"{a.memory_gb} GB per node, {a.bytes_per_atom} B per atom")
print("| nodes | atoms per rank | memory per node (GB) | t_comp (ms) | ghosts per rank | "
      "t_comm (ms) | t_step (ms) | comm share |")
print("|---|---|---|---|---|---|---|---|")
for nodes in (1, 10, 1000):
    ranks = nodes * a.cores
    n = a.atoms / ranks
    ghosts = calibration * shell(n)
    t_comp = a.compute_us * 1e-6 * n
    # every step: the ghosts' positions (24 B each) from up to 26 neighbours, all
    # ranks of a node through its link; 4 small all-reduces of log2(P) stages
    forward = 26 * alpha + a.cores * 24 * ghosts * beta
    reduces = 4 * alpha * math.log2(max(ranks, 2))
    # every rebuild: ids and positions of the new ghosts (32 B) and the migrants
    rebuild = (26 * alpha + a.cores * 32 * ghosts * beta) / a.rebuild_every
    t_comm = forward + reduces + rebuild
    memory = a.atoms / nodes * a.bytes_per_atom / 1e9
    fits = "" if memory <= a.memory_gb else " (does not fit)"
    t = t_comp + t_comm
    print(f"| {nodes} | {n:.3g} | {memory:.0f}{fits} | {1e3 * t_comp:.3g} | {ghosts:.3g} | "
          f"{1e3 * t_comm:.3g} | {1e3 * t:.3g} | {t_comm / t:.1%} |")

gamma = a.pair_ns * 1e-9
# a stage: gamma n^2 of sums against alpha + beta (32 n) bytes of the next block
b = 32 * beta
n_mask = (b + math.sqrt(b * b + 4 * gamma * alpha)) / (2 * gamma)
print()
print(f"# ring pass (gravity direct): a stage computes gamma n^2 = {a.pair_ns} ns x n^2 while "
      f"alpha + beta 32 n travels")
print(f"# masked once n >= {n_mask:.0f} bodies per rank "
      f"(gamma n^2 >= alpha + 32 beta n); at N = 1e6 on 64000 ranks, n = {1e6 / 64000:.0f}")
