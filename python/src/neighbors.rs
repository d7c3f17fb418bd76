//! `cellist.neighbors` and `cellist.NeighborList`: the engine's sorted half list
//! in vesin's shape, numpy in and numpy out, with the GIL released while it runs.

use crate::errors::value_error;
use crate::threads::pool;
use cellist_sim::neighbors::{
    half_list_in_box, GeometryError, Order, PairArrays, PairQuantities, SkinList,
};
use cellist_sim::Threads;
use numpy::{AllowTypeChange, IntoPyArray, PyArrayLike2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use std::borrow::Cow;

/// The letters of `quantities` checked: which arrays to return, in order.
fn parse_quantities(quantities: &str) -> PyResult<(Vec<char>, PairQuantities)> {
    let letters: Vec<char> = quantities.chars().collect();
    if letters.is_empty() {
        return Err(value_error(
            "quantities is empty; give letters among i, j, d, D, S (e.g. \"ijd\")",
        ));
    }
    for (k, &c) in letters.iter().enumerate() {
        if letters[..k].contains(&c) {
            return Err(value_error(format!(
                "quantities '{quantities}' names '{c}' twice; name each array once"
            )));
        }
        if !"ijdDS".contains(c) {
            return Err(value_error(format!(
                "quantities: unknown letter '{c}'; expected letters among i (first index), j (second \
                 index), d (distance), D (separation vector), S (image shift)"
            )));
        }
    }
    let wanted = PairQuantities {
        distances: letters.contains(&'d'),
        vectors: letters.contains(&'D'),
        shifts: letters.contains(&'S'),
    };
    Ok((letters, wanted))
}

/// The periodic flags: `periodic` as one bool or one per axis; `None` means
/// periodic where a box is given and open without one.
fn periodic_axes<const D: usize>(
    periodic: Option<&Bound<'_, PyAny>>,
    has_box: bool,
) -> PyResult<[bool; D]> {
    let Some(p) = periodic else {
        return Ok([has_box; D]);
    };
    let flags: Vec<bool> = if let Ok(all) = p.extract::<bool>() {
        vec![all; D]
    } else {
        p.extract::<Vec<bool>>().map_err(|_| {
            value_error(format!(
                "periodic must be a bool or a sequence of {D} bools"
            ))
        })?
    };
    if flags.len() != D {
        return Err(value_error(format!(
            "periodic has {} entries but the points are {D}D; give {D}",
            flags.len()
        )));
    }
    let flags: [bool; D] = std::array::from_fn(|a| flags[a]);
    if !has_box && flags.iter().any(|&f| f) {
        return Err(value_error(
            "periodic boundaries need a box: give box=[Lx, Ly(, Lz)], or periodic=False",
        ));
    }
    Ok(flags)
}

/// The box sides, each finite and > 0 (ones where there is no box: only the
/// periodic axes use them).
fn box_sides<const D: usize>(sides: Option<Vec<f64>>) -> PyResult<[f64; D]> {
    let Some(sides) = sides else {
        return Ok([1.0; D]);
    };
    if sides.len() != D {
        return Err(value_error(format!(
            "box has {} sides but the points are {D}D; give {D} sides (an orthorhombic box from the origin)",
            sides.len()
        )));
    }
    if let Some(bad) = sides.iter().find(|&&l| !(l.is_finite() && l > 0.0)) {
        return Err(value_error(format!(
            "box sides must be finite and > 0, got {bad}"
        )));
    }
    Ok(std::array::from_fn(|a| sides[a]))
}

/// The points' coordinates, row after row, and their dimension (2 or 3): an
/// (N, D) float64 array, converted once from other dtypes or lists; all finite.
fn point_data<'a>(
    points: &'a PyArrayLike2<'_, f64, AllowTypeChange>,
) -> PyResult<(Cow<'a, [f64]>, usize)> {
    let shape = points.shape();
    let dimension = shape[1];
    if !(dimension == 2 || dimension == 3) {
        return Err(value_error(format!(
            "points must be an (N, 2) or (N, 3) array, got shape ({}, {dimension})",
            shape[0]
        )));
    }
    // a C-ordered array is read in place; any other layout is copied once, row
    // after row
    let in_place = if points.is_c_contiguous() {
        points.as_slice().ok()
    } else {
        None
    };
    let flat: Cow<'a, [f64]> = match in_place {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(points.as_array().iter().copied().collect()),
    };
    if let Some(bad) = flat.iter().position(|x| !x.is_finite()) {
        return Err(value_error(format!(
            "points[{}, {}] is {}: every coordinate must be finite",
            bad / dimension,
            bad % dimension,
            flat[bad]
        )));
    }
    Ok((flat, dimension))
}

/// The arrays of `pairs` in the order of `letters` (each named once): one
/// array alone, else a tuple. No copy: each vector becomes the array's memory.
fn to_python<'py, const D: usize>(
    py: Python<'py>,
    letters: &[char],
    mut pairs: PairArrays,
) -> PyResult<Bound<'py, PyAny>> {
    let n = pairs.len();
    let mut out: Vec<Bound<'py, PyAny>> = Vec::with_capacity(letters.len());
    for &c in letters {
        let array = match c {
            'i' => std::mem::take(&mut pairs.i).into_pyarray(py).into_any(),
            'j' => std::mem::take(&mut pairs.j).into_pyarray(py).into_any(),
            'd' => std::mem::take(&mut pairs.distances)
                .into_pyarray(py)
                .into_any(),
            'D' => std::mem::take(&mut pairs.vectors)
                .into_pyarray(py)
                .reshape([n, D])?
                .into_any(),
            _ => std::mem::take(&mut pairs.shifts)
                .into_pyarray(py)
                .reshape([n, D])?
                .into_any(),
        };
        out.push(array);
    }
    if out.len() == 1 {
        Ok(out.swap_remove(0))
    } else {
        Ok(PyTuple::new(py, out)?.into_any())
    }
}

/// neighbors(points, cutoff, box=None, periodic=None, quantities="ij", threads=None, sorted=True)
/// --
///
/// The half neighbour list of `points` within `cutoff`: every pair i < j with
/// |x_j - x_i| < cutoff (minimum image on periodic axes), sorted by i then j in
/// input numbering -- exactly the pairs `cellist neighbors` prints.
///
/// points: an (N, 2) or (N, 3) float64 array (other dtypes and lists are
///     converted once).
/// box: the sides [Lx, Ly(, Lz)] of an orthorhombic box from the origin, or None.
/// periodic: a bool or one per axis; default periodic with a box, open without.
///     Open axes of a box span the points wherever they are.
/// quantities: letters among i, j (int64 indices), d (float64 distances),
///     D (float64 (P, dim) separations x_j - x_i), S (int32 (P, dim) image
///     shifts with x_j - x_i + S * box = D). One letter gives one array, more
///     give a tuple in that order.
/// threads: worker threads (default: the machine's cores). The result does not
///     depend on it.
/// sorted: False returns the same pairs in the order the cell list finds them
///     (fixed by the data, still i < j in each pair), as vesin's sorted=False:
///     about 2-3x faster for large random inputs.
#[pyfunction]
#[pyo3(signature = (points, cutoff, r#box=None, periodic=None, quantities="ij", threads=None, sorted=true))]
#[allow(clippy::too_many_arguments)]
pub fn neighbors<'py>(
    py: Python<'py>,
    points: PyArrayLike2<'py, f64, AllowTypeChange>,
    cutoff: f64,
    r#box: Option<Vec<f64>>,
    periodic: Option<&Bound<'py, PyAny>>,
    quantities: &str,
    threads: Option<usize>,
    sorted: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if !(cutoff.is_finite() && cutoff > 0.0) {
        return Err(value_error(format!(
            "cutoff must be finite and > 0, got {cutoff}"
        )));
    }
    let (letters, wanted) = parse_quantities(quantities)?;
    let pool = pool(threads)?;
    let has_box = r#box.is_some();
    let (flat, dimension) = point_data(&points)?;
    if dimension == 2 {
        let p = flat.as_chunks::<2>().0;
        let length = box_sides::<2>(r#box)?;
        let periodic = periodic_axes::<2>(periodic, has_box)?;
        let pairs = py.detach(|| search(p, length, periodic, cutoff, wanted, sorted, &pool))?;
        to_python::<2>(py, &letters, pairs)
    } else {
        let p = flat.as_chunks::<3>().0;
        let length = box_sides::<3>(r#box)?;
        let periodic = periodic_axes::<3>(periodic, has_box)?;
        let pairs = py.detach(|| search(p, length, periodic, cutoff, wanted, sorted, &pool))?;
        to_python::<3>(py, &letters, pairs)
    }
}

/// The half list of `points` in the box `length` with `periodic` axes, sorted
/// by `(i, j)` or as found.
fn search<const D: usize>(
    points: &[[f64; D]],
    length: [f64; D],
    periodic: [bool; D],
    cutoff: f64,
    wanted: PairQuantities,
    sorted: bool,
    pool: &Threads,
) -> PyResult<PairArrays> {
    let order = if sorted {
        Order::Sorted
    } else {
        Order::AsFound
    };
    half_list_in_box(points, length, periodic, cutoff, wanted, order, pool)
        .map_err(|e| value_error(e.flagged("cutoff").to_string()))
}

/// The lists of one dimension.
enum Skin {
    Two(SkinList<2>),
    Three(SkinList<3>),
}

/// NeighborList(cutoff, skin=0.0, box=None, periodic=None, quantities="ij", threads=None)
/// --
///
/// A neighbour list kept between calls: `update(points)` returns what
/// `neighbors` would (the same pairs; distances and separations to rounding),
/// and searches anew only when some point has moved more than skin / 2 since
/// the last search (or the number of points changed). `searches` counts them.
#[pyclass(module = "cellist")]
pub struct NeighborList {
    cutoff: f64,
    skin: f64,
    sides: Option<Vec<f64>>,
    periodic: Option<Py<PyAny>>,
    letters: Vec<char>,
    wanted: PairQuantities,
    pool: Threads,
    list: Option<Skin>,
}

#[pymethods]
impl NeighborList {
    #[new]
    #[pyo3(signature = (cutoff, skin=0.0, r#box=None, periodic=None, quantities="ij", threads=None))]
    fn new(
        cutoff: f64,
        skin: f64,
        r#box: Option<Vec<f64>>,
        periodic: Option<Py<PyAny>>,
        quantities: &str,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        if !(cutoff.is_finite() && cutoff > 0.0) {
            return Err(value_error(format!(
                "cutoff must be finite and > 0, got {cutoff}"
            )));
        }
        if !(skin.is_finite() && skin >= 0.0) {
            return Err(value_error(format!(
                "skin must be finite and >= 0, got {skin}"
            )));
        }
        let (letters, wanted) = parse_quantities(quantities)?;
        if let Some(sides) = &r#box {
            // the sides are checked against the points' dimension at update
            match sides.len() {
                2 => drop(box_sides::<2>(Some(sides.clone()))?),
                3 => drop(box_sides::<3>(Some(sides.clone()))?),
                n => {
                    return Err(value_error(format!(
                        "box has {n} sides; give 2 or 3 (an orthorhombic box from the origin)"
                    )))
                }
            }
        }
        Ok(NeighborList {
            cutoff,
            skin,
            sides: r#box,
            periodic,
            letters,
            wanted,
            pool: pool(threads)?,
            list: None,
        })
    }

    /// update(points)
    /// --
    ///
    /// The pairs of `points` within the cutoff now, as `neighbors` returns them.
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        points: PyArrayLike2<'py, f64, AllowTypeChange>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (flat, dimension) = point_data(&points)?;
        let has_box = self.sides.is_some();
        let periodic = self.periodic.as_ref().map(|p| p.bind(py).clone());
        let fresh = |list: &Option<Skin>| match list {
            Some(Skin::Two(_)) => dimension != 2,
            Some(Skin::Three(_)) => dimension != 3,
            None => true,
        };
        if fresh(&self.list) {
            self.list = Some(if dimension == 2 {
                let length = box_sides::<2>(self.sides.clone())?;
                let axes = periodic_axes::<2>(periodic.as_ref(), has_box)?;
                Skin::Two(SkinList::new(
                    length,
                    [0.0; 2],
                    axes,
                    self.cutoff,
                    self.skin,
                ))
            } else {
                let length = box_sides::<3>(self.sides.clone())?;
                let axes = periodic_axes::<3>(periodic.as_ref(), has_box)?;
                Skin::Three(SkinList::new(
                    length,
                    [0.0; 3],
                    axes,
                    self.cutoff,
                    self.skin,
                ))
            });
        }
        let (wanted, pool) = (self.wanted, &self.pool);
        let box_error = |e: GeometryError| value_error(format!("box: {e}"));
        match &mut self.list {
            Some(Skin::Two(l)) => {
                let p = flat.as_chunks::<2>().0;
                let pairs = py.detach(|| l.update(p, wanted, pool)).map_err(box_error)?;
                to_python::<2>(py, &self.letters, pairs)
            }
            Some(Skin::Three(l)) => {
                let p = flat.as_chunks::<3>().0;
                let pairs = py.detach(|| l.update(p, wanted, pool)).map_err(box_error)?;
                to_python::<3>(py, &self.letters, pairs)
            }
            None => Err(value_error("no list")),
        }
    }

    /// Number of searches (cell list and pairs within cutoff + skin) so far.
    #[getter]
    fn searches(&self) -> u64 {
        match &self.list {
            Some(Skin::Two(l)) => l.searches(),
            Some(Skin::Three(l)) => l.searches(),
            None => 0,
        }
    }

    /// The cutoff.
    #[getter]
    fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// The skin.
    #[getter]
    fn skin(&self) -> f64 {
        self.skin
    }
}
