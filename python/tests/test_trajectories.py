"""GSD trajectories read back by the gsd package, and VTK PolyData files that
parse as XML with the declared sizes."""

import pathlib
import xml.etree.ElementTree as ET

import gsd.hoomd
import numpy as np
import pytest

import cellist
from conftest import ROOT, md_scenario

MD_GSD = md_scenario(steps=30) + """gsd = { every = 10, file = "traj.gsd" }
vtk = { every = 15, file = "traj.pvd" }
checkpoint = { every = 20, file = "state.ckpt" }
"""


def test_gsd_frames_hold_the_positions_box_and_step(tmp_path):
    with cellist.Simulation.from_toml(MD_GSD, threads=1, out=tmp_path) as sim:
        sim.run()
        positions = sim.positions.copy()
        velocities = sim.velocities.copy()
    with gsd.hoomd.open(tmp_path / "traj.gsd") as traj:
        assert len(traj) == 4
        assert [f.configuration.step for f in traj] == [0, 10, 20, 30]
        last = traj[-1]
        side = (256 / 0.8442) ** (1 / 3)
        np.testing.assert_allclose(last.configuration.box, [side, side, side, 0, 0, 0],
                                   rtol=1e-7)
        assert last.particles.N == 256
        # HOOMD boxes are centred at the origin; the schema stores float32
        np.testing.assert_allclose(last.particles.position + side / 2, positions,
                                   rtol=0, atol=2e-5 * side)
        np.testing.assert_allclose(last.particles.velocity, velocities, rtol=1e-6, atol=1e-6)
        force = last.log["particles/force"]
        assert force.dtype == np.float64 and force.shape == (256, 3)


def test_a_restart_continues_the_gsd_file(tmp_path):
    with cellist.Simulation.from_toml(MD_GSD, threads=1, out=tmp_path / "whole") as sim:
        sim.run()
    first = cellist.Simulation.from_toml(MD_GSD, threads=1, out=tmp_path / "parts")
    first.run(20)
    first.save_checkpoint(tmp_path / "at20.ckpt")
    first.run(10)  # frame 30 written, then cut by the restart from step 20
    first.close()
    with gsd.hoomd.open(tmp_path / "parts" / "traj.gsd") as traj:
        assert len(traj) == 4
    again = cellist.Simulation.restart(tmp_path / "at20.ckpt", MD_GSD, threads=1,
                                       out=tmp_path / "parts")
    again.run()
    again.close()
    whole = (tmp_path / "whole" / "traj.gsd")
    with gsd.hoomd.open(whole) as a, gsd.hoomd.open(tmp_path / "parts" / "traj.gsd") as b:
        assert [f.configuration.step for f in b] == [f.configuration.step for f in a]
        for fa, fb in zip(a, b):
            np.testing.assert_array_equal(fa.particles.position, fb.particles.position)


def test_write_gsd_appends_frames(tmp_path):
    path = tmp_path / "by-hand.gsd"
    with cellist.Simulation.from_toml(str(ROOT / "examples" / "vortex-pair.toml"), threads=1,
                                      out=tmp_path / "out") as sim:
        sim.write_gsd(path)
        sim.run(2)
        sim.write_gsd(path)
        gamma = sim.circulations.copy()
    with gsd.hoomd.open(path) as traj:
        assert [f.configuration.step for f in traj] == [0, 2]
        assert traj[1].configuration.dimensions == 2
        np.testing.assert_array_equal(traj[1].log["particles/gamma"], gamma)


def test_vtk_series_parse_with_the_declared_sizes(tmp_path):
    with cellist.Simulation.from_toml(MD_GSD, threads=1, out=tmp_path) as sim:
        sim.run()
    index = ET.parse(tmp_path / "traj.pvd").getroot()
    files = [d.get("file") for d in index.iter("DataSet")]
    assert files == ["traj_00000000.vtp", "traj_00000015.vtp", "traj_00000030.vtp"]
    for name in files:
        piece = ET.parse(tmp_path / name).getroot().find("PolyData/Piece")
        n = int(piece.get("NumberOfPoints"))
        assert n == 256
        points = piece.find("Points/DataArray")
        assert len(points.text.split()) == 3 * n
        for array in piece.find("PointData"):
            components = int(array.get("NumberOfComponents", "1"))
            assert len(array.text.split()) == components * n, array.get("Name")


def test_bad_trajectory_keys_are_refused(tmp_path):
    bad = md_scenario(steps=5) + 'gsd = { every = 0, file = "t.gsd" }\n'
    with pytest.raises(ValueError, match="output.gsd.every must be >= 1"):
        cellist.Simulation.from_toml(bad, out=tmp_path)
    bad = md_scenario(steps=5) + 'vtk = { every = 1, file = "t.vtp" }\n'
    with pytest.raises(ValueError, match=r"output.vtk.file must end in .pvd"):
        cellist.Simulation.from_toml(bad, out=tmp_path)


def test_trajectory_files_stay_in_the_output_folder(tmp_path):
    bad = md_scenario(steps=5) + 'vtk = { every = 1, file = "sub/t.pvd" }\n'
    with pytest.raises(ValueError, match="must be a file name in the output folder"):
        cellist.Simulation.from_toml(bad, out=tmp_path)
