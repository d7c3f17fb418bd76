//! File formats for cellist: point files (plain text, extended XYZ), pair lists,
//! LAMMPS data files and dumps, GSD trajectories, VTK PolyData, checkpoints, and
//! output files that appear whole or not at all or grow as a run goes.
#![warn(missing_docs)]
// Loops over the three axes index several per-axis arrays at once.
#![allow(clippy::needless_range_loop)]

pub mod billiards;
pub mod bodies;
pub mod body_picture;
pub mod chart_gif;
pub mod checkpoint;
pub mod disc_picture;
pub mod dump;
pub mod error;
pub mod field_chart;
pub mod field_csv;
pub mod field_picture;
pub mod gsd;
pub mod lammps_data;
pub mod output;
pub mod parts;
pub mod plot;
pub mod points;
#[cfg(test)]
mod test_png;
pub mod vtk;

pub use billiards::{
    parse_billiards_input, read_billiards_input, write_state, BilliardsInput, StateFormat,
    TrajectoryReader, TrajectoryStep,
};
pub use bodies::{parse_bodies, read_bodies, read_bodies_part, BodyFile};
pub use body_picture::{body_chart, BodyCanvas, BodyChart, Plane};
pub use chart_gif::ChartPalette;
pub use checkpoint::{read_checkpoint, write_checkpoint, Checkpoint};
pub use disc_picture::{DiscPainter, GifAnimation};
pub use dump::{
    write_lammps_head, write_lammps_rows, write_xyz_head, write_xyz_rows, Frame, DUMP_COLUMNS,
    GRAVITY_DUMP_COLUMNS,
};
pub use error::InputError;
pub use field_chart::{field_chart, palette_rgb, write_chart, FieldChart};
pub use field_csv::{
    field_header, parse_field, parse_field_columns, read_field, read_field_columns, read_field_of,
    write_field, write_field_columns,
};
pub use field_picture::FieldPainter;
pub use gsd::{
    write_hoomd_frame, GsdData, GsdWriter, HoomdBlocks, HoomdFrame, HoomdHead, HoomdRows,
};
pub use lammps_data::{
    decode_data, decode_data_where, parse_data, read_data_box, read_data_where, AtomsWanted,
    DataAtom, DataFile,
};
pub use output::{format_g17, write_pairs, AtomicFile, StreamFile};
pub use parts::{Parts, Whole};
pub use points::{read_points, BoxInfo, PointFile, Points};
pub use vtk::{write_pvd, write_vtp, VtpBlocks};
