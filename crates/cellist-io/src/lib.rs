//! File formats for cellist: point files (plain text, extended XYZ), pair lists,
//! and output files that appear whole or not at all.
#![warn(missing_docs)]

pub mod error;
pub mod output;
pub mod plot;
pub mod points;

pub use error::InputError;
pub use output::{format_g17, write_pairs, AtomicFile};
pub use points::{read_points, BoxInfo, PointFile, Points};
