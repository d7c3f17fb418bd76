//! `cellist billiards check`: a per-step trajectory checked against its input
//! as the course's grader checks it.

use crate::error::{SimError, SimResult};
use cellist::models::billiards::{check_step, DiscState, StepChecker, Table};
use cellist::Threads;
use cellist_io::{read_billiards_input, TrajectoryReader};
use std::io::BufReader;
use std::path::Path;

/// The grader's verdict on a trajectory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Every step passed.
    Pass {
        /// Steps checked.
        steps: u64,
        /// The input's step count S.
        input_steps: u64,
    },
    /// The first fault: `FAIL at step k: <check>: <what>`, or a trajectory
    /// with no steps or steps out of order.
    Fail(String),
}

/// Checks the trajectory file `trajectory` (steps 1, 2, ... in order) against
/// the input `input` (its warnings go to standard error): ids, positions moved
/// by the previous velocity, energy and momentum per group, no collision left.
pub fn check(input: &Path, trajectory: &Path, threads: &Threads) -> SimResult<Verdict> {
    let input = read_billiards_input(input)?;
    for w in &input.warnings {
        eprintln!("warning: {w}");
    }
    let table = Table {
        side: input.side,
        radius: input.radius,
    };
    let n = input.ids.len();
    let mut prev: Vec<DiscState> = vec![[0.0; 4]; n];
    for (k, &id) in input.ids.iter().enumerate() {
        prev[id as usize] = [input.x[k], input.y[k], input.v[k][0], input.v[k][1]];
    }
    let file = std::fs::File::open(trajectory)
        .map_err(|e| SimError::Input(format!("{}: cannot read: {e}", trajectory.display())))?;
    let mut reader = TrajectoryReader::new(trajectory, BufReader::new(file), n);
    let mut checker = StepChecker::new(&table);
    let mut steps = 0u64;
    while let Some(block) = reader.next_step()? {
        if block.step != steps as i64 + 1 {
            return Ok(Verdict::Fail(format!(
                "FAIL: expected the block of step {}, found step {} (the file must hold steps 1, 2, ... in order)",
                steps + 1,
                block.step
            )));
        }
        match check_step(
            &mut checker,
            &table,
            &prev,
            &block.ids,
            &block.states,
            threads,
        ) {
            Ok(next) => prev = next,
            Err(fault) => {
                return Ok(Verdict::Fail(format!(
                    "FAIL at step {}: {fault}",
                    block.step
                )))
            }
        }
        steps += 1;
    }
    if steps == 0 {
        return Ok(Verdict::Fail("FAIL: the trajectory holds no step".into()));
    }
    Ok(Verdict::Pass {
        steps,
        input_steps: input.steps,
    })
}
