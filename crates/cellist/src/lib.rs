//! cellist: a particle-simulation engine.
//!
//! The engine holds the geometry (boxes, boundaries, minimum image), the neighbour
//! search (cell lists, Verlet lists, their traversals) and the race-free parallel
//! pair sums on an explicit thread pool. It does no I/O and prints nothing.
#![warn(missing_docs)]
// Loops over axes index several per-axis arrays (position, length, boundary) at once.
#![allow(clippy::needless_range_loop)]

pub mod decomposition;
pub mod geometry;
pub mod interactions;
pub mod interpolation;
pub mod longrange;
pub mod memory;
pub mod models;
pub mod neighbors;
pub mod random;
pub mod simd;
pub mod state;
pub mod threads;

pub use geometry::{Boundary, Domain, GeometryError};
pub use neighbors::{CellList, StencilKind, VerletList};
pub use threads::Threads;
