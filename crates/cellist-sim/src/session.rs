//! A run kept under way between calls: what the Python module's `Simulation`
//! steps. The scenario builds the model as for `cellist run`, the same driver
//! steps it ([`Live`]), and the same observers write its outputs; a session only
//! decides how far to go at each call.

use crate::driver::{Job, Live};
use crate::error::{SimError, SimResult};
use crate::hosted::Hosted;
use crate::launch::{begin, Launch, RunContext};
use crate::models::launch_scenario;
use crate::observers::OutputPlan;
use crate::scenario::Scenario;
use cellist::models::{Blowup, Model};
use cellist::Threads;
use cellist_io::checkpoint::{write_checkpoint, Checkpoint};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A model under way with its outputs, stepped on request.
pub trait Session {
    /// The model in its current state.
    fn model(&self) -> &dyn Model;

    /// The current step; the time is `step * dt`.
    fn step(&self) -> u64;

    /// The scenario's last step (`run.steps`).
    fn scenario_steps(&self) -> u64;

    /// Steps on to step `to` of a run whose last step is `last >= to`, with the
    /// observers, checks and checkpoints of `cellist run` (observers and
    /// checkpoints take the last step). A blow-up leaves the session at its
    /// last good state.
    fn advance(&mut self, to: u64, last: u64, threads: &Threads) -> SimResult;

    /// The last blow-up met, if any: the session went back to its last good
    /// state then.
    fn last_blowup(&self) -> Option<&Blowup>;

    /// Replaces the per-particle array `name` by `values`, where the model
    /// allows it ([`Hosted::set_array`]).
    fn set_array(&mut self, name: &str, values: &[f64], threads: &Threads) -> SimResult;

    /// The checkpoint of the current state.
    fn checkpoint(&mut self) -> SimResult<Checkpoint>;

    /// Writes the checkpoint of the current state to `path` (atomically).
    fn save_checkpoint(&mut self, path: &Path) -> SimResult {
        let c = self.checkpoint()?;
        write_checkpoint(path, &c).map_err(SimError::output(path.display().to_string()))
    }

    /// Completes the output files that are made at the end (plots, animations).
    fn finish_outputs(&mut self) -> SimResult;

    /// The named per-particle arrays of the current state ([`named_arrays`]).
    fn arrays(&self) -> Vec<NamedArray> {
        named_arrays(self.model(), self.step())
    }
}

/// A per-particle array in the user's particle order: its name, its values
/// (row after row) and its columns per particle.
pub type NamedArray = (String, Vec<f64>, usize);

/// The per-particle arrays of `model` at `step`, in the user's particle order:
/// the particles' (positions, velocities, forces, masses, ...) or the field's
/// (positions, the field values under their own name, the extra columns), and
/// the model's own names for them (strengths, circulations).
pub fn named_arrays(model: &dyn Model, step: u64) -> Vec<NamedArray> {
    let mut out: Vec<NamedArray> = Vec::new();
    let vectors = |v: &[[f64; 3]], d: usize| -> Vec<f64> {
        v.iter().flat_map(|x| x[..d].iter().copied()).collect()
    };
    if let Some(p) = model.particles(step, false) {
        let d = p.dimension;
        out.push(("ids".into(), p.ids.iter().map(|&i| i as f64).collect(), 1));
        if !p.types.is_empty() {
            out.push((
                "types".into(),
                p.types.iter().map(|&t| t as f64).collect(),
                1,
            ));
        }
        out.push(("positions".into(), vectors(&p.positions, d), d));
        out.push(("velocities".into(), vectors(&p.velocities, d), d));
        if !p.forces.is_empty() {
            out.push(("forces".into(), vectors(&p.forces, d), d));
        }
        if let Some(m) = p.masses {
            out.push(("masses".into(), m, 1));
        }
        if let Some(a) = p.accelerations {
            out.push(("accelerations".into(), vectors(&a, d), d));
        }
        if let Some(phi) = p.potentials {
            out.push(("potentials".into(), phi, 1));
        }
    } else if let Some(f) = model.field() {
        let d = f.dimension;
        out.push(("positions".into(), vectors(&f.positions, d), d));
        if let Some(strengths) = f.strengths {
            out.push(("strengths".into(), strengths, 1));
        }
        out.push((f.value_name.to_string(), f.values, 1));
        let extra = |name: &str| f.extra.iter().find(|(n, _)| *n == name).map(|(_, v)| v);
        // vectors kept in columns of their own: (u, v[, w]), (ax, ay, az)
        let vector = |names: &[&str]| -> Option<Vec<f64>> {
            let columns: Vec<&Vec<f64>> = names.iter().map(|n| extra(n)).collect::<Option<_>>()?;
            Some(
                (0..columns[0].len())
                    .flat_map(|i| columns.iter().map(move |c| c[i]))
                    .collect(),
            )
        };
        let velocity_names: &[&str] = if d == 3 {
            &["u", "v", "w"]
        } else {
            &["u", "v"]
        };
        let grouped: [(&str, &[&str]); 2] = [
            ("velocities", velocity_names),
            ("strengths", &["ax", "ay", "az"]),
        ];
        let mut taken: Vec<&str> = vec!["gamma"];
        for (name, names) in grouped {
            if let Some(values) = vector(names) {
                out.push((name.into(), values, names.len()));
                taken.extend_from_slice(names);
            }
        }
        if let Some(gamma) = extra("gamma") {
            out.push(("circulations".into(), gamma.clone(), 1));
        }
        for (name, values) in &f.extra {
            if !taken.contains(name) {
                out.push((name.to_string(), values.clone(), 1));
            }
        }
    }
    out
}

impl<M: Hosted + 'static> Session for Live<M> {
    fn model(&self) -> &dyn Model {
        Live::<M>::model(self)
    }

    fn step(&self) -> u64 {
        Live::<M>::step(self)
    }

    fn scenario_steps(&self) -> u64 {
        Live::scenario_steps(self)
    }

    fn advance(&mut self, to: u64, last: u64, threads: &Threads) -> SimResult {
        Live::advance(self, to, last, threads)
    }

    fn last_blowup(&self) -> Option<&Blowup> {
        Live::last_blowup(self)
    }

    fn set_array(&mut self, name: &str, values: &[f64], threads: &Threads) -> SimResult {
        Live::set_array(self, name, values, threads)
    }

    fn checkpoint(&mut self) -> SimResult<Checkpoint> {
        Live::checkpoint(self)
    }

    fn finish_outputs(&mut self) -> SimResult {
        Live::finish_outputs(self)
    }
}

/// The launch of a session: the run begun (restart applied, observers made,
/// step 0 observed) and kept.
pub struct Open;

impl Launch for Open {
    type Output = Box<dyn Session>;

    fn launch<M: Hosted + 'static>(
        self,
        job: Job<M>,
        plan: &OutputPlan,
        context: &RunContext,
        _started: Instant,
    ) -> SimResult<Box<dyn Session>> {
        // a session may have run past the scenario's last step: any
        // checkpoint step is accepted
        Ok(Box::new(begin(
            job,
            plan,
            context,
            u64::MAX,
            ProgressBar::hidden(),
        )?))
    }
}

/// Opens a session of `scenario` writing into `out_dir`, from the checkpoint
/// `restart` if given, quietly: the set-up's warnings are returned with it.
pub fn open(
    scenario: &Scenario,
    out_dir: PathBuf,
    restart: Option<&Path>,
    threads: &Threads,
) -> SimResult<(Box<dyn Session>, Vec<String>)> {
    let context = RunContext::new(out_dir, restart, threads).quiet();
    let session = launch_scenario(scenario, &context, Open)?;
    Ok((session, context.warnings.take()))
}
