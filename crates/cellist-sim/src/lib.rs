//! The simulation layer of cellist, the one door to the engine: a scenario's
//! keys become a model, and one driver loop runs every model with its observers
//! (thermo, dumps, fields, pictures, trajectories), checkpoints and restarts, and
//! blow-up stops; every workload the command line and the Python module run
//! (runs, studies, benchmarks, neighbour lists, the collision benchmark's
//! commands) is a function here that takes plain arguments and returns its
//! result or writes its files. Distributed runs on MPI (feature `mpi`) go through the same launch.
#![warn(missing_docs)]

pub mod bench;
pub mod billiards;
#[cfg(feature = "mpi")]
pub mod distributed;
pub mod driver;
pub mod error;
pub mod hosted;
pub mod launch;
pub mod models;
pub mod neighbors;
pub mod observers;
pub mod progress;
pub mod ranks;
pub mod scenario;
pub mod session;
pub mod study;
pub mod summary;

pub use error::{SimError, SimResult};
pub use launch::{RunContext, RunSummary};
pub use models::{run, run_scenario, RunRequest};
pub use scenario::Scenario;

// the engine's types that the command line and the Python module name
pub use cellist::models::billiards::{CellShape, DEFAULT_MAX_SWEEPS};
pub use cellist::models::Blowup;
pub use cellist::Threads;
pub use cellist_io::{checkpoint, StateFormat};
