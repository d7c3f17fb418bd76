//! `cellist neighbors`: the neighbour list of a point file.

use crate::cli::NeighborsArgs;
use crate::error::{positive, threads, CliError, CliResult};
use cellist::neighbors::half_pairs;
use cellist::{Boundary, CellList, Domain, Threads};
use cellist_io::{read_points, write_pairs, AtomicFile, BoxInfo, Points};
use rayon::slice::ParallelSliceMut;
use std::io::Write;

/// Runs the command.
pub fn run(args: &NeighborsArgs) -> CliResult {
    let cutoff = positive("--cutoff", args.cutoff)?;
    let pool = threads(args.threads)?;
    let file = read_points(&args.input)?;
    match file.points {
        Points::Two(p) => list::<2>(args, cutoff, &p, file.cell.as_ref(), &pool),
        Points::Three(p) => list::<3>(args, cutoff, &p, file.cell.as_ref(), &pool),
    }
}

fn list<const D: usize>(
    args: &NeighborsArgs,
    cutoff: f64,
    points: &[[f64; D]],
    file_box: Option<&BoxInfo>,
    pool: &Threads,
) -> CliResult {
    let domain = domain::<D>(args, points, file_box)?;
    let cells = CellList::build(&domain, cutoff, points)
        .map_err(|e| CliError::Input(format!("--cutoff {cutoff}: {e}")))?;
    let mut pairs = half_pairs(&cells, cutoff, pool, |i, j, r2| (i, j, r2.sqrt()));
    if !args.count {
        pool.install(|| pairs.par_sort_unstable_by_key(|p| ((p.0 as u64) << 32) | p.1 as u64));
    }
    let write = |out: &mut dyn Write| -> std::io::Result<()> {
        if args.count {
            writeln!(out, "{}", pairs.len())
        } else {
            write_pairs(out, pairs.iter().copied())
        }
    };
    match &args.output {
        Some(path) => {
            let what = path.display().to_string();
            let mut file = AtomicFile::create(path).map_err(CliError::output(&what))?;
            write(file.writer()).map_err(CliError::output(&what))?;
            file.commit().map_err(CliError::output(what))
        }
        None => {
            let stdout = std::io::stdout();
            let mut out = std::io::BufWriter::with_capacity(1 << 20, stdout.lock());
            write(&mut out)
                .and_then(|_| out.flush())
                .map_err(CliError::output("standard output"))
        }
    }
}

/// The domain from the flags and the file: a box (from --box, else the file's)
/// is periodic unless --open; without a box the points get open boundaries.
fn domain<const D: usize>(
    args: &NeighborsArgs,
    points: &[[f64; D]],
    file_box: Option<&BoxInfo>,
) -> CliResult<Domain<D>> {
    let (lengths, origin, file_periodic) = match (&args.box_lengths, file_box) {
        (Some(l), _) => {
            if l.len() != D {
                return Err(CliError::Input(format!(
                    "--box has {} lengths but {} holds {D}D points; give {D} lengths",
                    l.len(),
                    args.input.display()
                )));
            }
            if let Some(&bad) = l.iter().find(|&&v| !(v.is_finite() && v > 0.0)) {
                return Err(CliError::Input(format!(
                    "--box lengths must be finite and > 0, got {bad}"
                )));
            }
            (l.clone(), vec![0.0; D], vec![true; D])
        }
        (None, Some(b)) => (b.lengths.clone(), b.origin.clone(), b.periodic.clone()),
        (None, None) => {
            if args.periodic {
                return Err(CliError::Input(
                    "--periodic needs a box: give --box, or an XYZ file with a Lattice".into(),
                ));
            }
            return Ok(Domain::open_around(points));
        }
    };
    let boundary: [Boundary; D] = std::array::from_fn(|d| {
        let periodic = if args.open {
            false
        } else {
            args.periodic || file_periodic[d]
        };
        if periodic {
            Boundary::Periodic
        } else {
            Boundary::Open
        }
    });
    if boundary.iter().all(|&b| b == Boundary::Open) {
        return Ok(Domain::open_around(points));
    }
    let mut domain = Domain::new(std::array::from_fn(|d| lengths[d]), boundary)
        .map_err(|e| CliError::Input(format!("box: {e}")))?;
    domain.lo = std::array::from_fn(|d| origin[d]);
    // open axes of a partly periodic box span the points, wherever they are
    let (lo, hi) = cellist::geometry::bounding_box(points);
    for d in 0..D {
        if boundary[d] == Boundary::Open && !points.is_empty() {
            domain.lo[d] = lo[d];
            domain.length[d] = (hi[d] - lo[d]).max(f64::MIN_POSITIVE);
        }
    }
    Ok(domain)
}
