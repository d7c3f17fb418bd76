//! The output plan of a run: which observers a scenario asks for, built for
//! its model.

use super::dumps::{Dump, DumpPlan};
use super::fields::{FieldFiles, FieldPlan};
use super::observer::{Observer, Recorded};
use super::pictures::{BodyPictures, BodyPlan};
use super::thermo::{PlotSpec, TableStyle, Thermo};
use super::trajectories::{GsdTrajectory, VtkSeries};
use crate::error::SimResult;
use crate::scenario::keys::TrajectoryKeys;
use cellist::models::Model;
use std::path::Path;

/// The outputs of a scenario run: thermo, dumps and field snapshots.
#[derive(Clone, Debug)]
pub struct OutputPlan {
    /// Steps between thermo rows (0: the first and last step only).
    pub thermo_every: u64,
    /// The terminal table's format.
    pub table: TableStyle,
    /// The plot of thermo columns.
    pub plot: Option<PlotSpec>,
    /// Dumps.
    pub dumps: Vec<DumpPlan>,
    /// Field snapshots.
    pub field: Option<FieldPlan>,
    /// Pictures of the bodies.
    pub bodies: Option<BodyPlan>,
    /// GSD and VTK trajectories.
    pub trajectories: TrajectoryKeys,
}

/// What makes a run's observers: a scenario's [`OutputPlan`], or the outputs
/// of `cellist billiards run`.
pub trait Outputs<M> {
    /// The observers for `model`, writing to `dir` (continuing the `recorded`
    /// files of a restart); `quiet` prints no thermo table.
    fn observers(
        &self,
        model: &M,
        dir: &Path,
        recorded: Recorded,
        quiet: bool,
    ) -> SimResult<Vec<Box<dyn Observer<M>>>>;
}

impl<M: Model + 'static> Outputs<M> for OutputPlan {
    fn observers(
        &self,
        model: &M,
        dir: &Path,
        recorded: Recorded,
        quiet: bool,
    ) -> SimResult<Vec<Box<dyn Observer<M>>>> {
        let mut observers: Vec<Box<dyn Observer<M>>> = vec![Box::new(Thermo::new(
            model,
            self.thermo_every,
            self.table,
            self.plot.clone(),
            dir,
            recorded,
            quiet,
        )?)];
        for d in &self.dumps {
            observers.push(Box::new(Dump::new(
                d.every,
                &d.file,
                d.columns.clone(),
                d.format,
                dir,
                recorded,
            )?));
        }
        if let Some(f) = &self.field {
            observers.push(Box::new(FieldFiles::new(model, f, dir, recorded)?));
        }
        if let Some(b) = &self.bodies {
            observers.push(Box::new(BodyPictures::new(b, dir, recorded)?));
        }
        if let Some(keys) = &self.trajectories.gsd {
            observers.push(Box::new(GsdTrajectory::new(keys, dir, recorded)?));
        }
        if let Some(keys) = &self.trajectories.vtk {
            observers.push(Box::new(VtkSeries::new(keys, model.dt(), dir)));
        }
        Ok(observers)
    }
}
