"""cellist.neighbors and cellist.NeighborList against a brute-force numpy half
list and against `cellist neighbors`."""

import numpy as np
import pytest

import cellist


def brute_force(points, cutoff, box, periodic):
    """Every pair i < j within the cutoff, minimum image on the periodic axes."""
    n, dim = points.shape
    i, j = np.triu_indices(n, k=1)
    d = points[j] - points[i]
    for a in range(dim):
        if periodic[a]:
            d[:, a] -= box[a] * np.round(d[:, a] / box[a])
    r = np.sqrt((d * d).sum(axis=1))
    keep = r < cutoff
    return i[keep], j[keep], r[keep], d[keep]


CASES = [
    (2, [True, True]),
    (3, [True, True, True]),
    (2, [False, False]),
    (3, [False, False, False]),
    (3, [True, False, True]),
    (2, [False, True]),
]


@pytest.mark.parametrize("dim,periodic", CASES)
@pytest.mark.parametrize("seed", [1, 2])
def test_neighbors_equal_brute_force(dim, periodic, seed):
    rng = np.random.default_rng(seed)
    box = rng.uniform(5.0, 9.0, size=dim)
    points = rng.uniform(0.0, 1.0, size=(300, dim)) * box
    cutoff = 1.7
    i, j, d, D, S = cellist.neighbors(points, cutoff, box=box.tolist(), periodic=periodic,
                                      quantities="ijdDS", threads=2)
    bi, bj, bd, bD = brute_force(points, cutoff, box, periodic)
    assert len(i) > 100
    assert i.dtype == np.int64 and j.dtype == np.int64
    assert d.dtype == np.float64 and D.dtype == np.float64 and S.dtype == np.int32
    assert D.shape == (len(i), dim) and S.shape == (len(i), dim)
    np.testing.assert_array_equal(i, bi)
    np.testing.assert_array_equal(j, bj)
    np.testing.assert_allclose(d, bd, rtol=0, atol=1e-12)
    np.testing.assert_allclose(D, bD, rtol=0, atol=1e-12)
    # the shifts: x_j - x_i + S * box = D
    np.testing.assert_allclose(points[j] - points[i] + S * box, D, rtol=0, atol=1e-12)
    assert np.all(S[:, ~np.array(periodic)] == 0)


def test_points_outside_the_box_and_other_dtypes():
    rng = np.random.default_rng(5)
    box = np.array([6.0, 7.0, 8.0])
    points = rng.uniform(-1.0, 2.0, size=(200, 3)) * box
    i, j, d = cellist.neighbors(points.tolist(), 2.0, box=box, quantities="ijd")
    bi, bj, bd, _ = brute_force(points, 2.0, box, [True] * 3)
    np.testing.assert_array_equal(i, bi)
    np.testing.assert_array_equal(j, bj)
    np.testing.assert_allclose(d, bd, rtol=0, atol=1e-12)
    # float32 input is converted once; a non-contiguous view works too
    view = np.asfortranarray(points)
    i2, j2 = cellist.neighbors(view, 2.0, box=box)
    np.testing.assert_array_equal(i2, bi)
    one = cellist.neighbors(points, 2.0, box=box, quantities="d")
    np.testing.assert_array_equal(one, d)


def test_the_thread_count_does_not_change_the_bits():
    rng = np.random.default_rng(9)
    points = rng.uniform(0.0, 10.0, size=(2000, 3))
    one = cellist.neighbors(points, 1.5, box=[10.0] * 3, quantities="ijdDS", threads=1)
    two = cellist.neighbors(points, 1.5, box=[10.0] * 3, quantities="ijdDS", threads=2)
    for a, b in zip(one, two):
        assert a.tobytes() == b.tobytes()


def test_neighbors_equal_the_command_line(cli, tmp_path):
    rng = np.random.default_rng(3)
    points = rng.uniform(0.0, 8.0, size=(500, 3))
    path = tmp_path / "points.txt"
    np.savetxt(path, points, fmt="%.17g")
    printed = cli("neighbors", "--input", path, "--cutoff", 1.5, "--box", 8, 8, 8)
    rows = [line.split() for line in printed.splitlines() if line and not line.startswith("#")]
    # the file holds exactly the text numpy wrote: read back the same doubles
    points = np.loadtxt(path)
    i, j, d = cellist.neighbors(points, 1.5, box=[8.0, 8.0, 8.0], quantities="ijd")
    assert len(rows) == len(i) > 0
    assert [int(r[0]) for r in rows] == i.tolist()
    assert [int(r[1]) for r in rows] == j.tolist()
    assert [float(r[2]) for r in rows] == d.tolist()


def test_bad_input_raises_value_error_with_the_reason():
    points = np.zeros((4, 3))
    with pytest.raises(ValueError, match="cutoff must be finite and > 0"):
        cellist.neighbors(points, -1.0)
    with pytest.raises(ValueError, match=r"\(N, 2\) or \(N, 3\)"):
        cellist.neighbors(np.zeros((4, 4)), 1.0)
    with pytest.raises(ValueError, match="box has 2 sides but the points are 3D"):
        cellist.neighbors(points, 1.0, box=[1.0, 2.0])
    with pytest.raises(ValueError, match="periodic boundaries need a box"):
        cellist.neighbors(points, 1.0, periodic=True)
    with pytest.raises(ValueError, match="unknown letter 'x'"):
        cellist.neighbors(points, 1.0, quantities="ijx")
    with pytest.raises(ValueError, match="must be finite"):
        cellist.neighbors(np.array([[0.0, np.nan, 0.0]]), 1.0)
    with pytest.raises(ValueError, match="cutoff"):
        cellist.neighbors(points, 3.0, box=[4.0, 4.0, 4.0])


def test_neighbor_list_keeps_its_search_while_points_move_little():
    rng = np.random.default_rng(11)
    box = [9.0, 9.0, 9.0]
    points = rng.uniform(0.0, 9.0, size=(1500, 3))
    nl = cellist.NeighborList(2.0, skin=0.5, box=box, quantities="ijd")
    for _ in range(12):
        i, j, d = nl.update(points)
        ri, rj, rd = cellist.neighbors(points, 2.0, box=box, quantities="ijd")
        np.testing.assert_array_equal(i, ri)
        np.testing.assert_array_equal(j, rj)
        np.testing.assert_allclose(d, rd, rtol=0, atol=1e-12)
        points = points + rng.uniform(-0.04, 0.04, size=points.shape)
    assert 1 < nl.searches < 12


def test_neighbor_list_in_2d_with_open_axes_and_every_quantity():
    rng = np.random.default_rng(4)
    points = rng.uniform(0.0, 12.0, size=(800, 2))
    nl = cellist.NeighborList(1.2, skin=0.3, box=[12.0, 12.0], periodic=[True, False],
                              quantities="ijdDS")
    for _ in range(4):
        got = nl.update(points)
        want = cellist.neighbors(points, 1.2, box=[12.0, 12.0], periodic=[True, False],
                                 quantities="ijdDS")
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        np.testing.assert_allclose(got[2], want[2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(got[3], want[3], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(got[4], want[4])
        points = points + rng.uniform(-0.05, 0.05, size=points.shape)
    with pytest.raises(ValueError, match="box sides must be finite and > 0"):
        cellist.NeighborList(1.0, box=[1.0, -2.0])
    with pytest.raises(ValueError, match="skin must be finite and >= 0"):
        cellist.NeighborList(1.0, skin=-0.1)


@pytest.mark.parametrize("dim,periodic", [(3, [True, False, True]), (2, [True, True])])
def test_the_list_as_found_holds_the_same_pairs(dim, periodic):
    rng = np.random.default_rng(21)
    box = [7.0] * dim
    points = rng.uniform(0.0, 7.0, size=(600, dim))
    want = cellist.neighbors(points, 1.6, box=box, periodic=periodic, quantities="ijdDS")
    for threads in (1, 2):
        got = cellist.neighbors(points, 1.6, box=box, periodic=periodic, quantities="ijdDS",
                                threads=threads, sorted=False)
        assert np.all(got[0] < got[1])
        order = np.lexsort((got[1], got[0]))
        for a, b in zip(got, want):
            np.testing.assert_array_equal(a[order], b)
