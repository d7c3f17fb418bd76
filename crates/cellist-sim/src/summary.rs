//! `summary.json`: what a run did and what it cost, written into its output
//! folder at the end of the run (also after a blow-up, with what was done so
//! far). Its keys are a contract (`docs/models.md`):
//!
//! ```text
//! cellist_version, model, scenario, outcome ("completed" | "blow-up"),
//! first_step, last_step, steps, particles, threads, ranks,
//! wall_seconds, loop_seconds, stage_seconds { stage: seconds },
//! communication_seconds, imbalance_particles, imbalance_busy,   # null in one process
//! peak_rss_bytes
//! ```
//!
//! On several MPI ranks every rank measures its share and rank 0 writes the
//! figures reduced over the ranks: the largest communication time during the
//! loop, the largest over mean busy time (the loop less the communication) and
//! the largest peak resident memory; the particles are those of every rank, the
//! times of the loop and its stages rank 0's.

use crate::driver::{self, Live, Timing};
use crate::error::{SimError, SimResult};
use crate::hosted::{Distribution, Hosted};
use crate::ranks::Ranks;
use cellist_io::AtomicFile;
use serde::{Serialize, Serializer};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The file's name in the output folder.
pub const FILE: &str = "summary.json";

/// How a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Outcome {
    /// It ran to its last step.
    Completed,
    /// It stopped on a blow-up (exit status 3).
    BlowUp,
}

/// The time per stage as a JSON object, in the order of the speed line's table.
#[derive(Debug)]
struct Stages(Vec<(&'static str, f64)>);

impl Serialize for Stages {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(self.0.iter().copied())
    }
}

/// What `summary.json` holds, in its order.
#[derive(Debug, Serialize)]
struct Summary {
    cellist_version: &'static str,
    model: &'static str,
    scenario: Option<String>,
    outcome: Outcome,
    first_step: u64,
    last_step: u64,
    steps: u64,
    particles: usize,
    threads: usize,
    ranks: i32,
    wall_seconds: f64,
    loop_seconds: f64,
    stage_seconds: Stages,
    #[serde(flatten)]
    spread: Spread,
    peak_rss_bytes: Option<u64>,
}

/// The figures of a run over several MPI ranks, reduced over the ranks; `null`
/// in one process.
#[derive(Debug, Default, Serialize)]
struct Spread {
    communication_seconds: Option<f64>,
    imbalance_particles: Option<f64>,
    imbalance_busy: Option<f64>,
}

impl Spread {
    /// The figures of this rank's distribution `now` (its communication less
    /// the `before` the loop) over a loop of `loop_seconds`, reduced over
    /// `ranks` (collective).
    fn reduce(ranks: &Ranks, now: Distribution, before: Duration, loop_seconds: f64) -> Self {
        let communication = now.communication.saturating_sub(before).as_secs_f64();
        let busy = (loop_seconds - communication).max(0.0);
        let [most_communication, most_busy] = ranks.largest([communication, busy]);
        let [all_busy] = ranks.sum([busy]);
        let mean_busy = all_busy / f64::from(ranks.count());
        Spread {
            communication_seconds: Some(most_communication),
            imbalance_particles: Some(now.imbalance_particles),
            imbalance_busy: (mean_busy > 0.0).then(|| most_busy / mean_busy),
        }
    }
}

/// A run's `summary.json` to come: where it goes, what the run was read
/// from, its threads, when its set-up began and the communication time of this
/// rank before the loop (the set-up's exchanges, left out of the loop's).
pub(crate) struct Pending {
    dir: PathBuf,
    scenario: Option<String>,
    threads: usize,
    started: Instant,
    before: Duration,
}

impl Pending {
    /// The summary of `live`, about to run its loop on `threads` threads,
    /// read from `scenario`, writing into `dir`, whose set-up began at
    /// `started`; `None` for a run without an output folder (`cellist
    /// billiards run`).
    pub(crate) fn new<M: Hosted>(
        live: &Live<M>,
        dir: &Path,
        scenario: Option<&Path>,
        threads: usize,
        started: Instant,
    ) -> Option<Self> {
        (!dir.as_os_str().is_empty()).then(|| Pending {
            dir: dir.to_path_buf(),
            scenario: scenario.map(|p| p.display().to_string()),
            threads,
            started,
            before: live
                .ranks()
                .distribution(live.model())
                .map_or(Duration::ZERO, |d| d.communication),
        })
    }

    /// Measures the run of `model` on `ranks`, which took its loop from
    /// `timing.first` to `last` and ended with `outcome`, and writes the file
    /// on the rank that writes outputs. Collective on several ranks: every
    /// rank calls it.
    pub(crate) fn write<M: Hosted>(
        &self,
        model: &M,
        ranks: &Ranks,
        timing: Timing,
        last: u64,
        outcome: Outcome,
    ) -> SimResult {
        let loop_seconds = timing.loop_time.as_secs_f64();
        let [peak] = ranks.largest([peak_rss_bytes().unwrap_or(0) as f64]);
        let now = ranks.distribution(model);
        let particles = now.map_or(model.len(), |d| d.particles);
        let spread = now.map_or_else(Spread::default, |now| {
            Spread::reduce(ranks, now, self.before, loop_seconds)
        });
        if !ranks.writes_output() {
            return Ok(());
        }
        let stages = driver::stages(model, timing.loop_time, timing.output_time);
        let summary = Summary {
            cellist_version: env!("CARGO_PKG_VERSION"),
            model: model.info().name,
            scenario: self.scenario.clone(),
            outcome,
            first_step: timing.first,
            last_step: last,
            steps: last - timing.first,
            particles,
            threads: self.threads,
            ranks: ranks.count(),
            wall_seconds: self.started.elapsed().as_secs_f64(),
            loop_seconds,
            stage_seconds: Stages(stages.iter().map(|(n, d)| (*n, d.as_secs_f64())).collect()),
            spread,
            peak_rss_bytes: (peak > 0.0).then_some(peak as u64),
        };
        let path = self.dir.join(FILE);
        let what = path.display().to_string();
        let mut file = AtomicFile::create(&path).map_err(SimError::output(what.clone()))?;
        serde_json::to_writer_pretty(file.writer(), &summary)
            .map_err(std::io::Error::from)
            .and_then(|()| writeln!(file.writer()))
            .and_then(|()| file.commit())
            .map_err(SimError::output(what))
    }
}

/// The peak resident memory of this process (`VmHWM` in `/proc/self/status`)
/// in bytes; `None` where the system has no such file.
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?;
    let kib: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
    Some(kib * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_rss_is_read_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(peak_rss_bytes().is_some_and(|b| b > 0));
        }
    }

    #[test]
    fn stages_keep_their_order() {
        let stages = Stages(vec![("Neighbor", 1.0), ("Force", 2.5), ("Other", 0.0)]);
        let text = serde_json::to_string(&stages).unwrap();
        assert_eq!(text, r#"{"Neighbor":1.0,"Force":2.5,"Other":0.0}"#);
        let outcome = serde_json::to_string(&Outcome::BlowUp).unwrap();
        assert_eq!(outcome, r#""blow-up""#);
    }
}
