//! The course grader's checks of one step (SPEC.md section 6), with its tolerances:
//! positions moved by the previous velocities, energy per group, momentum per group
//! away from walls, and no definite collision left. Any resolution order that
//! follows the rules passes; the checks do not know the canonical order.

use super::components::SlotSets;
use super::contacts::{Contact, ContactGrid};
use super::rules::Table;
use crate::threads::Threads;
use std::fmt;

/// Absolute and relative tolerance of the checks.
const TOL: f64 = 1e-4;
/// Slack on the squared contact distance.
const NEAR: f64 = 1e-7;

/// One disc as a trajectory reports it: `[x, y, vx, vy]`.
pub type DiscState = [f64; 4];

/// The first check a step fails, with the particle (id) or group it concerns.
#[derive(Clone, Debug, PartialEq)]
pub enum CheckFailure {
    /// A step with other than N particles.
    Count {
        /// Particles listed.
        found: usize,
        /// N.
        expected: usize,
    },
    /// An id outside `0..N`.
    IdOutOfRange {
        /// The id.
        id: i64,
    },
    /// An id seen twice.
    DuplicateId {
        /// The id.
        id: i64,
    },
    /// A position is not the previous position plus the previous velocity.
    Position {
        /// The particle.
        id: usize,
        /// 0 for x, 1 for y.
        axis: usize,
        /// Previous position + previous velocity.
        expected: f64,
        /// The position found.
        found: f64,
    },
    /// A group's energy changed.
    Energy {
        /// The group's smallest id.
        first: usize,
        /// Its size.
        size: usize,
        /// `sum (vx^2 + vy^2)` of its members before.
        before: f64,
        /// And now.
        after: f64,
    },
    /// The momentum of a group away from the walls changed.
    Momentum {
        /// The group's smallest id.
        first: usize,
        /// Its size.
        size: usize,
        /// 0 for x, 1 for y.
        axis: usize,
        /// The summed velocity component before.
        before: f64,
        /// And now.
        after: f64,
    },
    /// A particle still moves into a wall it overlaps.
    WallCollision {
        /// The particle.
        id: usize,
    },
    /// Two particles still overlap and approach.
    PairCollision {
        /// The smaller id.
        a: usize,
        /// The larger id.
        b: usize,
    },
}

impl fmt::Display for CheckFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const AXES: [&str; 2] = ["x", "y"];
        match self {
            CheckFailure::Count { found, expected } => {
                write!(f, "ids: {found} particles listed, expected {expected}")
            }
            CheckFailure::IdOutOfRange { id } => write!(f, "ids: particle id {id} is out of range"),
            CheckFailure::DuplicateId { id } => write!(f, "ids: particle id {id} appears twice"),
            CheckFailure::Position {
                id,
                axis,
                expected,
                found,
            } => write!(
                f,
                "position: particle {id} has {} = {found}, expected the previous position plus \
                 the previous velocity, {expected}",
                AXES[*axis]
            ),
            CheckFailure::Energy {
                first,
                size,
                before,
                after,
            } => write!(
                f,
                "energy: the group of particle {first} ({size} particles) had energy {before} \
                 and now {after}"
            ),
            CheckFailure::Momentum {
                first,
                size,
                axis,
                before,
                after,
            } => write!(
                f,
                "momentum: the group of particle {first} ({size} particles, away from the walls) \
                 had momentum {} = {before} and now {after}",
                AXES[*axis]
            ),
            CheckFailure::WallCollision { id } => write!(
                f,
                "collision left: particle {id} overlaps a wall and still moves into it"
            ),
            CheckFailure::PairCollision { a, b } => write!(
                f,
                "collision left: particles {a} and {b} overlap and still approach"
            ),
        }
    }
}

/// Buffers of the checker, kept between steps.
#[derive(Clone, Debug)]
pub struct StepChecker {
    grid: ContactGrid,
    near: Vec<Contact>,
    parent: Vec<u32>,
    x: Vec<f64>,
    y: Vec<f64>,
}

impl StepChecker {
    /// A checker for discs on `table`.
    pub fn new(table: &Table) -> Self {
        StepChecker {
            grid: table.grid(),
            near: Vec::new(),
            parent: Vec::new(),
            x: Vec::new(),
            y: Vec::new(),
        }
    }
}

/// `|new - old| > 1e-4` and `|new - old| / old > 1e-4`, `old` signed (as the grader).
fn exceeds(new: f64, old: f64) -> bool {
    let d = (new - old).abs();
    d > TOL && d / old > TOL
}

/// Checks one step: `prev` by id (the input or the last step), `ids` and `cur` in the
/// order the trajectory lists them. Returns the state by id for the next step.
pub fn check_step(
    checker: &mut StepChecker,
    table: &Table,
    prev: &[DiscState],
    ids: &[i64],
    cur: &[DiscState],
    threads: &Threads,
) -> Result<Vec<DiscState>, CheckFailure> {
    let n = prev.len();
    if ids.len() != n || cur.len() != n {
        return Err(CheckFailure::Count {
            found: ids.len().min(cur.len()),
            expected: n,
        });
    }
    let mut by_id: Vec<Option<DiscState>> = vec![None; n];
    for (&id, state) in ids.iter().zip(cur) {
        let slot = usize::try_from(id)
            .ok()
            .filter(|&k| k < n)
            .ok_or(CheckFailure::IdOutOfRange { id })?;
        if by_id[slot].replace(*state).is_some() {
            return Err(CheckFailure::DuplicateId { id });
        }
    }
    let c: Vec<DiscState> = by_id
        .into_iter()
        .map(|s| s.expect("N distinct ids in 0..N"))
        .collect();
    for axis in 0..2 {
        for (id, (p, s)) in prev.iter().zip(&c).enumerate() {
            let expected = p[axis] + p[axis + 2];
            if exceeds(expected, s[axis]) {
                return Err(CheckFailure::Position {
                    id,
                    axis,
                    expected,
                    found: s[axis],
                });
            }
        }
    }
    let StepChecker {
        grid,
        near,
        parent,
        x,
        y,
    } = checker;
    x.clear();
    x.extend(c.iter().map(|s| s[0]));
    y.clear();
    y.extend(c.iter().map(|s| s[1]));
    let lim = table.contact();
    grid.find(x, y, lim + NEAR, threads, near);
    parent.clear();
    parent.extend(0..n as u32);
    let mut sets = SlotSets { parent, first: 0 };
    for p in near.iter() {
        sets.union(p.a as usize, p.b as usize, |_| {});
    }
    // per group (indexed by its root, the smallest id): sums in id order
    let (r, l) = (table.radius_f(), table.side_f());
    let mut size = vec![0usize; n];
    let mut energy = vec![[0.0f64; 2]; n];
    let mut momentum = vec![[0.0f64; 4]; n];
    let mut walled = vec![false; n];
    for id in 0..n {
        let g = sets.root(id);
        let (p, s) = (&prev[id], &c[id]);
        size[g] += 1;
        energy[g][0] += p[2] * p[2] + p[3] * p[3];
        energy[g][1] += s[2] * s[2] + s[3] * s[3];
        for a in 0..2 {
            momentum[g][a] += p[a + 2];
            momentum[g][a + 2] += s[a + 2];
        }
        walled[g] |=
            s[0] - r <= TOL || s[0] + r >= l - TOL || s[1] - r <= TOL || s[1] + r >= l - TOL;
    }
    let groups = || (0..n).filter(|&g| size[g] > 0);
    if let Some(g) = groups().find(|&g| exceeds(energy[g][1], energy[g][0])) {
        return Err(CheckFailure::Energy {
            first: g,
            size: size[g],
            before: energy[g][0],
            after: energy[g][1],
        });
    }
    for axis in 0..2 {
        if let Some(g) =
            groups().find(|&g| !walled[g] && exceeds(momentum[g][axis + 2], momentum[g][axis]))
        {
            return Err(CheckFailure::Momentum {
                first: g,
                size: size[g],
                axis,
                before: momentum[g][axis],
                after: momentum[g][axis + 2],
            });
        }
    }
    let into_wall = |s: &DiscState| {
        (s[0] - r <= -TOL && s[2] < -TOL)
            || (s[0] + r >= l + TOL && s[2] > TOL)
            || (s[1] - r <= -TOL && s[3] < -TOL)
            || (s[1] + r >= l + TOL && s[3] > TOL)
    };
    if let Some(id) = c.iter().position(into_wall) {
        return Err(CheckFailure::WallCollision { id });
    }
    for p in near.iter() {
        let (sa, sb) = (&c[p.a as usize], &c[p.b as usize]);
        let dot = (sb[2] - sa[2]) * p.sep.dx + (sb[3] - sa[3]) * p.sep.dy;
        if p.sep.q <= lim - NEAR && dot < -TOL {
            return Err(CheckFailure::PairCollision {
                a: p.a as usize,
                b: p.b as usize,
            });
        }
    }
    Ok(c)
}
