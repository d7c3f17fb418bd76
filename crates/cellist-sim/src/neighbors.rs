//! Neighbour lists as the command line and the Python module ask for them: the
//! half list of a point file (`cellist neighbors`), and the half list of
//! points in a box, sorted by `(i, j)` or in the order the cells find the
//! pairs (`cellist.neighbors`, `cellist bench neighbors`).

use crate::error::{positive, SimError, SimResult};
use cellist::neighbors::{half_list_as_found, half_pairs, sorted_half_list};
use cellist::{CellList, Domain, Threads};
use cellist_io::{read_points, write_pairs, AtomicFile, BoxInfo, Points};
use std::io::Write;
use std::path::Path;

pub use cellist::neighbors::{PairArrays, PairQuantities, SkinList};
pub use cellist::GeometryError;

/// The order of the pairs of a half list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// Sorted by `(i, j)` in input numbering.
    Sorted,
    /// In the order the cells find them (fixed by the data), `i < j` in each.
    AsFound,
}

/// Why a search could not be made.
#[derive(Clone, Debug, PartialEq)]
pub enum SearchError {
    /// The box does not hold the points.
    Box(GeometryError),
    /// The cutoff does not fit the box (more than half a periodic side).
    Cutoff {
        /// The cutoff asked for.
        cutoff: f64,
        /// Why it does not fit.
        why: String,
    },
}

impl SearchError {
    /// The input error, naming the cutoff as the caller calls it
    /// (`"--cutoff"`, `"cutoff"`): `box: ...` or `<name> <cutoff>: ...`.
    pub fn flagged(&self, cutoff_name: &str) -> SimError {
        SimError::Input(match self {
            SearchError::Box(e) => format!("box: {e}"),
            SearchError::Cutoff { cutoff, why } => format!("{cutoff_name} {cutoff}: {why}"),
        })
    }
}

/// The cell list of `points` in `domain` for `cutoff`, or why the cutoff does
/// not fit the box.
pub fn cells<const D: usize>(
    domain: &Domain<D>,
    points: &[[f64; D]],
    cutoff: f64,
    threads: &Threads,
) -> Result<CellList<D>, SearchError> {
    CellList::build_in(domain, cutoff, points, threads).map_err(|e| SearchError::Cutoff {
        cutoff,
        why: e.to_string(),
    })
}

/// The half list of `points` in `domain`: every pair `i < j` closer than
/// `cutoff` (minimum image on periodic axes) with the `quantities` asked for,
/// in `order`.
pub fn half_list<const D: usize>(
    domain: &Domain<D>,
    points: &[[f64; D]],
    cutoff: f64,
    quantities: PairQuantities,
    order: Order,
    threads: &Threads,
) -> Result<PairArrays, SearchError> {
    let cells = cells(domain, points, cutoff, threads)?;
    Ok(match order {
        Order::Sorted => sorted_half_list(&cells, points, cutoff, quantities, threads),
        Order::AsFound => half_list_as_found(&cells, points, cutoff, quantities, threads),
    })
}

/// [`half_list`] of `points` in the orthorhombic box of sides `length` from the
/// origin, `periodic` per axis (open axes span the points wherever they are).
pub fn half_list_in_box<const D: usize>(
    points: &[[f64; D]],
    length: [f64; D],
    periodic: [bool; D],
    cutoff: f64,
    quantities: PairQuantities,
    order: Order,
    threads: &Threads,
) -> Result<PairArrays, SearchError> {
    let domain =
        Domain::for_points(points, length, [0.0; D], periodic).map_err(SearchError::Box)?;
    half_list(&domain, points, cutoff, quantities, order, threads)
}

/// What `cellist neighbors` asks for.
#[derive(Clone, Copy, Debug)]
pub struct NeighborsOfFile<'a> {
    /// The point file: plain text (2 or 3 coordinates a line) or extended XYZ.
    pub input: &'a Path,
    /// Pairs strictly closer than this are listed.
    pub cutoff: f64,
    /// Box sides (as many as the points' dimension), `[0, L)` on each axis.
    pub box_lengths: Option<&'a [f64]>,
    /// Periodic on every axis (the default with a box).
    pub periodic: bool,
    /// Open on every axis, even with a box.
    pub open: bool,
    /// Only the number of pairs.
    pub count: bool,
    /// Where the list goes (default: standard output).
    pub output: Option<&'a Path>,
}

/// `cellist neighbors`: reads the point file and writes its half list, one
/// `i j r` line per pair sorted by `(i, j)`, or the number of pairs, to the
/// output file (whole or not at all) or standard output.
pub fn neighbors_of_file(request: &NeighborsOfFile, threads: &Threads) -> SimResult {
    positive("--cutoff", request.cutoff)?;
    let file = read_points(request.input)?;
    match file.points {
        Points::Two(p) => list_of_file::<2>(request, &p, file.cell.as_ref(), threads),
        Points::Three(p) => list_of_file::<3>(request, &p, file.cell.as_ref(), threads),
    }
}

fn list_of_file<const D: usize>(
    request: &NeighborsOfFile,
    points: &[[f64; D]],
    file_box: Option<&BoxInfo>,
    threads: &Threads,
) -> SimResult {
    let cutoff = request.cutoff;
    let domain = domain_of_file::<D>(request, points, file_box)?;
    let cells = cells(&domain, points, cutoff, threads).map_err(|e| e.flagged("--cutoff"))?;
    let write = |out: &mut dyn Write| -> std::io::Result<()> {
        if request.count {
            // the count alone: no list in memory
            let pairs = half_pairs(&cells, cutoff, threads, |_, _, _| ());
            writeln!(out, "{}", pairs.len())
        } else {
            let quantities = PairQuantities {
                distances: true,
                ..PairQuantities::default()
            };
            let pairs = sorted_half_list(&cells, points, cutoff, quantities, threads);
            let rows = pairs.i.iter().zip(&pairs.j).zip(&pairs.distances);
            write_pairs(out, rows.map(|((&i, &j), &r)| (i as u32, j as u32, r)))
        }
    };
    match request.output {
        Some(path) => {
            let what = path.display().to_string();
            let mut file = AtomicFile::create(path).map_err(SimError::output(&what))?;
            write(file.writer()).map_err(SimError::output(&what))?;
            file.commit().map_err(SimError::output(what))
        }
        None => {
            let stdout = std::io::stdout();
            let mut out = std::io::BufWriter::with_capacity(1 << 20, stdout.lock());
            write(&mut out)
                .and_then(|_| out.flush())
                .map_err(SimError::output("standard output"))
        }
    }
}

/// The domain from the request and the file: a box (from `box_lengths`, else
/// the file's) is periodic unless `open`; without a box the points get open
/// boundaries.
fn domain_of_file<const D: usize>(
    request: &NeighborsOfFile,
    points: &[[f64; D]],
    file_box: Option<&BoxInfo>,
) -> SimResult<Domain<D>> {
    let (lengths, origin, file_periodic) = match (request.box_lengths, file_box) {
        (Some(l), _) => {
            if l.len() != D {
                return Err(SimError::Input(format!(
                    "--box has {} lengths but {} holds {D}D points; give {D} lengths",
                    l.len(),
                    request.input.display()
                )));
            }
            if let Some(&bad) = l.iter().find(|&&v| !(v.is_finite() && v > 0.0)) {
                return Err(SimError::Input(format!(
                    "--box lengths must be finite and > 0, got {bad}"
                )));
            }
            (l.to_vec(), vec![0.0; D], vec![true; D])
        }
        (None, Some(b)) => (b.lengths.clone(), b.origin.clone(), b.periodic.clone()),
        (None, None) => {
            if request.periodic {
                return Err(SimError::Input(
                    "--periodic needs a box: give --box, or an XYZ file with a Lattice".into(),
                ));
            }
            return Ok(Domain::open_around(points));
        }
    };
    let periodic: [bool; D] =
        std::array::from_fn(|d| !request.open && (request.periodic || file_periodic[d]));
    Domain::for_points(
        points,
        std::array::from_fn(|d| lengths[d]),
        std::array::from_fn(|d| origin[d]),
        periodic,
    )
    .map_err(|e| SimError::Input(format!("box: {e}")))
}
