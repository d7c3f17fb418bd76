//! `cellist neighbors`: the neighbour list of a point file, by the simulation
//! layer.

use crate::cli::NeighborsArgs;
use crate::error::{threads, CliResult};
use cellist_sim::neighbors::{neighbors_of_file, NeighborsOfFile};

/// Runs the command.
pub fn run(args: &NeighborsArgs) -> CliResult {
    let pool = threads(args.threads)?;
    let request = NeighborsOfFile {
        input: &args.input,
        cutoff: args.cutoff,
        box_lengths: args.box_lengths.as_deref(),
        periodic: args.periodic,
        open: args.open,
        count: args.count,
        output: args.output.as_deref(),
    };
    Ok(neighbors_of_file(&request, &pool)?)
}
