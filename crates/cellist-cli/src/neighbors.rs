//! `cellist neighbors`: the neighbour list of a point file.

use crate::cli::NeighborsArgs;
use crate::error::{positive, threads, CliError, CliResult};
use cellist::neighbors::{half_pairs, sorted_half_list, PairQuantities};
use cellist::{CellList, Domain, Threads};
use cellist_io::{read_points, write_pairs, AtomicFile, BoxInfo, Points};
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
    let cells = CellList::build_in(&domain, cutoff, points, pool)
        .map_err(|e| CliError::Input(format!("--cutoff {cutoff}: {e}")))?;
    let write = |out: &mut dyn Write| -> std::io::Result<()> {
        if args.count {
            // the count alone: no list in memory
            let pairs = half_pairs(&cells, cutoff, pool, |_, _, _| ());
            writeln!(out, "{}", pairs.len())
        } else {
            let quantities = PairQuantities {
                distances: true,
                ..PairQuantities::default()
            };
            let pairs = sorted_half_list(&cells, points, cutoff, quantities, pool);
            let rows = pairs.i.iter().zip(&pairs.j).zip(&pairs.distances);
            write_pairs(out, rows.map(|((&i, &j), &r)| (i as u32, j as u32, r)))
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
    let periodic: [bool; D] =
        std::array::from_fn(|d| !args.open && (args.periodic || file_periodic[d]));
    Domain::for_points(
        points,
        std::array::from_fn(|d| lengths[d]),
        std::array::from_fn(|d| origin[d]),
        periodic,
    )
    .map_err(|e| CliError::Input(format!("box: {e}")))
}
