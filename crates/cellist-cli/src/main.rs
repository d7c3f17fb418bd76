//! `cellist`: the command-line tool of the cellist particle-simulation engine.

mod bench;
mod billiards;
mod cli;
mod error;
mod neighbors;
mod run;
mod study;

use clap::Parser;
use cli::{BenchCommand, BilliardsCommand, Cli, Command};
use error::CliError;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = Cli::parse();
    #[cfg(feature = "mpi")]
    let _cluster = match distributed(&cli) {
        Ok(cluster) => cluster,
        Err(code) => return code,
    };
    let result = match cli.command {
        Command::Run(args) => run::run(&args),
        Command::Neighbors(args) => neighbors::run(&args),
        Command::Sweep(args) => study::sweep(&args),
        Command::Convergence(args) => study::convergence(&args),
        Command::Scaling(args) => study::scaling(&args),
        Command::Billiards { which } => match which {
            BilliardsCommand::Run(args) => billiards::run(&args),
            BilliardsCommand::Check(args) => billiards::check(&args),
            BilliardsCommand::Gen(args) => billiards::gen(&args),
            BilliardsCommand::Sweep(args) => billiards::sweep(&args),
        },
        Command::Bench { which } => match which {
            BenchCommand::Neighbors(args) => bench::neighbors(&args),
            BenchCommand::Lj(args) => bench::lj(&args),
            BenchCommand::Billiards(args) => bench::billiards(&args),
            BenchCommand::Pse(args) => bench::pse(&args),
            BenchCommand::Gravity(args) => bench::gravity(&args),
            BenchCommand::Vortex(args) => bench::vortex(&args),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is_broken_pipe() => ExitCode::SUCCESS,
        Err(CliError::Rejected(verdict)) => {
            println!("{verdict}");
            ExitCode::from(1)
        }
        Err(e) => {
            if !silent_rank() {
                eprintln!("error: {e}");
            }
            ExitCode::from(e.exit_code())
        }
    }
}

/// With the `mpi` feature: MPI starts once for the process. On one rank every
/// command runs as without MPI; on several, `cellist run` runs the models that
/// are distributed and refuses the others with one message from rank 0, and
/// every other command is refused too, every rank exiting with status 2.
#[cfg(feature = "mpi")]
fn distributed(cli: &Cli) -> Result<Option<cellist_sim::distributed::Cluster>, ExitCode> {
    let Some(cluster) = cellist_sim::distributed::Cluster::start() else {
        return Ok(None);
    };
    if cluster.ranks() == 1 {
        return Ok(Some(cluster));
    }
    let message = match &cli.command {
        Command::Run(args) => match cluster.refuse_run(args.scenario.as_deref(), &args.set) {
            None => return Ok(Some(cluster)),
            Some(e) => e.to_string(),
        },
        _ => "only `cellist run` runs on several MPI ranks; run this command without mpirun"
            .to_string(),
    };
    if cluster.rank() == 0 {
        eprintln!("error: {message}");
    }
    Err(ExitCode::from(2))
}

/// True on every rank but rank 0 of a run on several MPI ranks: errors are
/// agreed between the ranks, and rank 0 prints them.
fn silent_rank() -> bool {
    #[cfg(feature = "mpi")]
    {
        cellist_sim::distributed::rank_of_many().is_some_and(|rank| rank != 0)
    }
    #[cfg(not(feature = "mpi"))]
    {
        false
    }
}
