"""cellist.Simulation: the same bits as `cellist run`, checkpoints and pickles
that continue bit for bit, errors as exceptions, the GIL released while it runs."""

import pickle
import threading

import numpy as np
import pytest

import cellist
from conftest import md_scenario, read_dump_last_frame


def test_positions_after_run_equal_the_dump_of_cellist_run(cli, tmp_path):
    text = md_scenario(steps=40)
    scenario = tmp_path / "melt.toml"
    scenario.write_text(text)
    cli("run", scenario, "--out", tmp_path / "cli", "--threads", 1)
    dump = read_dump_last_frame(tmp_path / "cli" / "final.lammpstrj")
    with cellist.Simulation.from_toml(str(scenario), threads=2, out=tmp_path / "py") as sim:
        assert sim.model == "md" and sim.step == 0 and len(sim) == 256
        sim.run(25)
        sim.run(15)
        assert sim.step == 40 and sim.time == pytest.approx(0.2)
        positions, velocities = sim.positions, sim.velocities
        assert positions.shape == (256, 3) and positions.dtype == np.float64
        assert not positions.flags.writeable
        np.testing.assert_array_equal(positions[:, 0], dump["x"])
        np.testing.assert_array_equal(positions[:, 2], dump["z"])
        np.testing.assert_array_equal(velocities[:, 1], dump["vy"])
        thermo = sim.thermo()
        assert thermo["step"] == 40 and set(thermo) >= {"temp", "pe", "etotal"}
        ids = sim.arrays()["ids"]
        np.testing.assert_array_equal(ids, np.arange(1, 257))
    # the Python run wrote the same dump as the command line
    assert (tmp_path / "py" / "final.lammpstrj").read_bytes() == \
        (tmp_path / "cli" / "final.lammpstrj").read_bytes()


def test_a_pickled_simulation_continues_to_the_same_bits(tmp_path):
    sim = cellist.Simulation.from_toml(md_scenario(steps=60), threads=1, out=tmp_path / "a")
    sim.run(20)
    copy = pickle.loads(pickle.dumps(sim))
    assert copy.step == 20 and copy.model == "md"
    assert copy.out == tmp_path / "a-copy"  # never the original's files
    assert copy.thermo() == sim.thermo()
    sim.run(30)
    copy.run(30)
    assert sim.positions.tobytes() == copy.positions.tobytes()
    assert sim.velocities.tobytes() == copy.velocities.tobytes()
    sim.close()
    copy.close()


def test_a_checkpoint_restarts_to_the_same_bits(tmp_path):
    text = md_scenario(steps=50)
    whole = cellist.Simulation.from_toml(text, threads=1, out=tmp_path / "whole")
    whole.run()
    assert whole.step == 50
    first = cellist.Simulation.from_toml(text, threads=2, out=tmp_path / "parts")
    first.run(20)
    first.save_checkpoint(tmp_path / "at20.ckpt")
    first.close()
    second = cellist.Simulation.restart(tmp_path / "at20.ckpt", text, threads=1,
                                        out=tmp_path / "parts")
    assert second.step == 20
    second.run()
    assert second.step == 50
    assert second.positions.tobytes() == whole.positions.tobytes()
    whole.close()
    second.close()


def test_a_restart_with_other_physics_is_refused(tmp_path):
    sim = cellist.Simulation.from_toml(md_scenario(steps=10), threads=1, out=tmp_path)
    sim.run(5)
    sim.save_checkpoint(tmp_path / "c.ckpt")
    sim.close()
    other = md_scenario(steps=10).replace("dt = 0.005", "dt = 0.002")
    with pytest.raises(ValueError, match="the physics key `run.dt`"):
        cellist.Simulation.restart(tmp_path / "c.ckpt", other, out=tmp_path)


def test_bad_scenarios_raise_value_error_with_the_cli_message(tmp_path, cli):
    bad = md_scenario().replace("[pair]", "[pair]\ncutof = 2.5")
    with pytest.raises(ValueError, match="unknown field `cutof`"):
        cellist.Simulation.from_toml(bad, out=tmp_path)
    with pytest.raises(ValueError, match="cannot read"):
        cellist.Simulation.from_toml(str(tmp_path / "missing.toml"))
    with pytest.raises(ValueError, match="model 'plasma' is unknown"):
        cellist.Simulation.from_toml('model = "plasma"\n', out=tmp_path)


def test_a_blow_up_raises_blowup_with_step_particle_and_quantity(tmp_path):
    text = md_scenario(steps=200).replace("dt = 0.005", "dt = 0.5")
    sim = cellist.Simulation.from_toml(text, threads=1, out=tmp_path)
    with pytest.raises(cellist.BlowUp) as caught:
        sim.run()
    error = caught.value
    assert isinstance(error, RuntimeError)
    assert error.step >= 1 and error.particle is not None
    assert error.quantity is not None and "last good state" in str(error)
    # back at the last good state, which is finite
    assert sim.step < error.step
    assert np.all(np.isfinite(sim.positions))
    sim.close()


def test_run_releases_the_gil(tmp_path):
    """While a simulation runs in a thread, the main thread keeps running Python."""
    sim = cellist.Simulation.from_toml(md_scenario(steps=10_000), threads=1, out=tmp_path)
    done = threading.Event()

    def work():
        sim.run(300)
        done.set()

    worker = threading.Thread(target=work)
    worker.start()
    spins = 0
    while not done.is_set():
        spins += 1
    worker.join()
    assert sim.step == 300
    # a held GIL would let the main thread run only between the worker's
    # bytecodes: none while run() is inside Rust
    assert spins > 1000
    sim.close()


def test_two_simulations_in_two_threads_give_the_bits_of_one(tmp_path):
    results = {}

    def work(name):
        with cellist.Simulation.from_toml(md_scenario(steps=30), threads=1,
                                          out=tmp_path / name) as sim:
            sim.run()
            results[name] = sim.positions.tobytes()

    threads = [threading.Thread(target=work, args=(n,)) for n in ("a", "b")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert results["a"] == results["b"]


def test_other_models_expose_their_arrays(tmp_path, cli):
    examples = cellist_examples()
    with cellist.Simulation.from_toml(str(examples / "vortex-pair.toml"), threads=1,
                                      out=tmp_path / "vortex") as sim:
        gamma0 = sim.circulations.copy()
        sim.run(3)
        assert sim.positions.shape[1] == 2
        assert sim.circulations.shape == (len(sim),)
        assert sim.velocities.shape == (len(sim), 2)
        assert sim.circulations.sum() == pytest.approx(gamma0.sum(), rel=1e-9, abs=1e-12)
    ring = (examples / "vortex-ring.toml").read_text().replace(
        "core = 0.2, spacing = 0.1", "core = 0.4, spacing = 0.2").replace(
        "grid = 64", "grid = 16")
    with cellist.Simulation.from_toml(ring, threads=1, out=tmp_path / "ring") as sim:
        sim.run(2)
        n = len(sim)
        assert sim.positions.shape == (n, 3)
        assert sim.velocities.shape == (n, 3)
        assert sim.strengths.shape == (n, 3)
        # the ring moves along +z
        assert sim.velocities[:, 2].mean() > 0
    with cellist.Simulation.from_toml(str(examples / "gravity-two-body.toml"), threads=1,
                                      out=tmp_path / "gravity") as sim:
        sim.run(5)
        assert set(sim.arrays()) >= {"positions", "velocities", "masses", "accelerations"}
        assert sim.positions.shape == (len(sim), 2)  # dimension = 2: the plane z = 0
        with pytest.raises(AttributeError, match="has no array 'circulations'"):
            sim.circulations
    with cellist.Simulation.from_toml(str(examples / "pse-sine.toml"), threads=1,
                                      out=tmp_path / "pse") as sim:
        sim.run(2)
        arrays = sim.arrays()
        assert "phi" in arrays and sim.strengths.shape == arrays["phi"].shape


def cellist_examples():
    from conftest import ROOT
    return ROOT / "examples"


def test_set_positions_and_velocities_where_the_model_allows_it(tmp_path):
    with cellist.Simulation.from_toml(md_scenario(steps=20), threads=1, out=tmp_path) as sim:
        sim.run(5)
        moved = sim.positions * 0.999  # inside the box, so not wrapped
        sim.set_positions(moved)
        np.testing.assert_array_equal(sim.positions, moved)
        sim.set_velocities(np.zeros((len(sim), 3)))
        assert sim.thermo()["ke"] == 0.0
        assert np.abs(sim.forces).sum() > 0  # recomputed for the new positions
        sim.run(5)
        assert sim.thermo()["ke"] > 0.0
        with pytest.raises(ValueError, match=r"give an \(256, 3\) array"):
            sim.set_positions(np.zeros((10, 3)))
        with pytest.raises(ValueError, match="must be finite"):
            sim.set_velocities(np.full((256, 3), np.nan))
    gravity = cellist_examples() / "gravity-two-body.toml"
    with cellist.Simulation.from_toml(str(gravity), threads=1, out=tmp_path / "g") as sim:
        with pytest.raises(ValueError, match="model gravity does not allow setting its positions"):
            sim.set_positions(sim.positions)


def test_a_billiards_scenario_gives_the_golden_bits(tmp_path):
    """The collision benchmark's sample input run as a scenario: the final state
    equals the golden one bit for bit."""
    from conftest import ROOT
    data = ROOT.parent / "shared" / "testdata" / "billiards"
    if not data.exists():
        pytest.skip("../shared/testdata/billiards is not beside the project")
    scenario = f'model = "billiards"\ninput = "{data / "inputs" / "sample.in"}"\n'
    with cellist.Simulation.from_toml(scenario + "[output]\nthermo_every = 5\n", threads=2,
                                      out=tmp_path) as sim:
        assert sim.model == "billiards"
        sim.run()
        positions, velocities = sim.positions, sim.velocities
        energy = sim.thermo()["energy"]
    golden = [line.split() for line in
              (data / "golden" / "sample.final.bits").read_text().splitlines() if line.strip()]
    bits = lambda x: format(np.float64(x).view(np.uint64), "016x")
    assert len(golden) == len(positions)
    for row, x, v in zip(golden, positions, velocities):
        assert [bits(x[0]), bits(x[1]), bits(v[0]), bits(v[1])] == row[2:6]
    assert energy > 0


def test_thermo_after_a_restart_an_unpickling_and_a_blow_up(tmp_path):
    text = md_scenario(steps=30)
    sim = cellist.Simulation.from_toml(text, threads=1, out=tmp_path / "a")
    sim.run()
    sim.run(10)  # past run.steps
    sim.save_checkpoint(tmp_path / "at40.ckpt")
    expected = sim.thermo()
    copy = pickle.loads(pickle.dumps(sim))
    assert copy.step == 40
    again = cellist.Simulation.restart(tmp_path / "at40.ckpt", text, out=tmp_path / "b")
    for other in (copy, again):
        got = other.thermo()
        assert got["step"] == 40
        for key in ("temp", "ke"):
            assert got[key] == expected[key]
        for key in ("pe", "etotal", "press"):
            assert got[key] == pytest.approx(expected[key], rel=1e-12)
        other.close()
    sim.close()
    vortex = (cellist_examples() / "vortex-pair.toml").read_text().replace(
        "spacing = 0.01", "spacing = 0.03")
    with cellist.Simulation.from_toml(vortex, threads=1, out=tmp_path / "v") as v:
        v.run(4)
        row = v.thermo()
        restored = pickle.loads(pickle.dumps(v))
        assert restored.thermo() == row
        restored.close()
    blown = md_scenario(steps=200).replace("dt = 0.005", "dt = 0.5")
    with cellist.Simulation.from_toml(blown, threads=1, out=tmp_path / "c") as sim:
        with pytest.raises(cellist.BlowUp):
            sim.run()
        assert all(np.isfinite(v) for v in sim.thermo().values())


def test_ctrl_c_stops_a_run_at_a_step(tmp_path):
    import _thread
    import signal
    # a process started in the background by a shell without job control
    # ignores SIGINT, and then interrupt_main() does nothing: Python's own
    # handler, as in an interactive session
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    sim = cellist.Simulation.from_toml(md_scenario(steps=10), threads=1, out=tmp_path)
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            sim.run(10_000_000)
    finally:
        timer.join()
        signal.signal(signal.SIGINT, previous)
    stopped = sim.step
    assert 0 < stopped < 10_000_000
    sim.run(5)
    assert sim.step == stopped + 5
    sim.close()
