"""cellist: particle simulations and neighbour lists, numpy in, numpy out.

- ``neighbors(points, cutoff, box=None, periodic=None, quantities="ij")``: the
  half neighbour list, as ``cellist neighbors`` prints it.
- ``NeighborList(cutoff, skin=0.0, ...)``: the same, kept between calls.
- ``Simulation.from_toml(path_or_text)``: any scenario of ``cellist run``
  (md, pse, gravity, vortex), stepped from Python.
- ``BlowUp``: the exception of a run that blew up.
"""

from ._cellist import BlowUp, NeighborList, Simulation, __version__, neighbors

__all__ = ["BlowUp", "NeighborList", "Simulation", "neighbors", "__version__"]
