//! The hard-disk collision benchmark of seed 001 (CS3210 "particles go brr"), as
//! `../shared/testdata/billiards/SPEC.md` states it: identical discs in a square box
//! with walls, moved each step, then wall and pair collisions resolved with frozen
//! positions until none is left.
//!
//! One step:
//! ```text
//! move:     x <- x + vx, y <- y + vy                       (every disc)
//! resolve:  repeat { walls in vector order; pairs (a, b) in lexicographic order }
//!           until a sweep changes nothing                   (Gauss-Seidel)
//! ```
//! The resolution runs in the canonical order of SPEC.md section 4, bit for bit,
//! but only over the candidates (discs on a wall, overlapping pairs, found on a grid:
//! E1) and separately for each connected component of the overlap graph (E2), the
//! components in parallel. Results are the same bits for any thread count.

mod check;
mod components;
mod contacts;
mod error;
mod generate;
mod model;
mod rules;
mod system;

pub use check::{check_step, CheckFailure, DiscState, StepChecker};
pub use contacts::{CellShape, Contact, ContactGrid};
pub use error::BilliardsError;
pub use generate::{separated_discs, uniform_discs, Drawn};
pub use model::{BilliardsModel, INFO};
pub use rules::{Separation, Table, Walls, APPROACH};
pub use system::{Billiards, StepStats, DEFAULT_MAX_SWEEPS};
