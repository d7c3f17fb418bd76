//! Observers: what the driver does after a step when their trigger fires. Each
//! is written once, in a file of its own, and works for every model that
//! declares what it needs: thermo rows (and the plot drawn from them), LAMMPS
//! and extended XYZ dumps, field files, pictures (written by [`Snapshots`]) and
//! GSD and VTK trajectories. Files that grow as the run goes are
//! [`StreamFile`](cellist_io::StreamFile)s, so that a restart continues them
//! from the lengths its checkpoint recorded. The [`OutputPlan`] of a scenario
//! says which observers a run has.

mod dumps;
mod fields;
mod observer;
mod pictures;
mod plan;
mod thermo;
mod trajectories;

pub use dumps::{write_frame, Dump, DumpFormat, DumpPlan};
pub use fields::{write_field_csv, ChartLabels, FieldFiles, FieldPlan};
pub use observer::{open_stream, Every, Observer, Recorded};
pub use pictures::{
    snapshot_path, snapshot_title, BodyPictures, BodyPlan, SnapshotFiles, Snapshots,
};
pub use plan::{OutputPlan, Outputs};
pub use thermo::{PlotSpec, TableStyle, Thermo};
pub use trajectories::{open_gsd, GsdTrajectory, TrajectoryFrame, VtkSeries};
