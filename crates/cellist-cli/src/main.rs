//! `cellist`: the command-line tool of the cellist particle-simulation engine.

mod bench;
mod billiards;
mod cli;
mod error;
mod gravity;
mod neighbors;
mod pse;
mod run;
mod study;
mod vortex;

use clap::Parser;
use cli::{BenchCommand, BilliardsCommand, Cli, Command};
use error::CliError;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = Cli::parse();
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
            BenchCommand::Billiards(args) => billiards::bench(&args),
            BenchCommand::Pse(args) => pse::bench(&args),
            BenchCommand::Gravity(args) => gravity::bench(&args),
            BenchCommand::Vortex(args) => vortex::bench(&args),
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
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
