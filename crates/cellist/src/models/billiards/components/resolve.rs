//! The components' columns and their resolution: [`Components`], the buffers of
//! a step kept between steps (filled by `label.rs` and `group.rs`), and the
//! canonical loop run on every component at once, each on its own block of
//! velocities, its pairs level by level, four disjoint pairs at a time in SIMD
//! lanes; then the velocities written back.
//!
//! `Components` and the types of its resolution's columns are defined here, not
//! in a file of their own, because rustc compiles a type's methods in the
//! codegen unit of the module that defines the type: so the resolution's
//! parallel loop, [`Component::settle`] and [`LocalPairs`]' columns stay in one
//! unit and are inlined as when all of `components` was one file (the same
//! machine code for the loop).

use super::levels::Staged;
use crate::models::billiards::rules::{collide_four, Separation, Walls};
use crate::simd::F64x4;
use crate::threads::{fill_in_parts, scatter_in_parts, DisjointSlice, Threads};
use rayon::prelude::*;

/// The pairs of all components by positions within their component's block,
/// structure of arrays, ordered by component, then level, then canonical order.
#[derive(Clone, Debug, Default)]
pub(super) struct LocalPairs {
    pub(super) a: Vec<u32>,
    pub(super) b: Vec<u32>,
    pub(super) dx: Vec<f64>,
    pub(super) dy: Vec<f64>,
    pub(super) q: Vec<f64>,
}

/// A disc of a component's block: its velocity (16 bytes, so that four share a
/// cache line).
#[derive(Clone, Copy, Debug)]
pub(super) struct LocalDisc {
    pub(super) v: [f64; 2],
}

/// The components of one step and their buffers (kept between steps). The discs
/// are seen by *slot*: their places in a spatial order (the contact grid's
/// cells), so that the discs of a component, and the passes over them, lie close
/// together in memory; `number[slot]` is a disc's vector position, which alone
/// decides the canonical order.
#[derive(Clone, Debug, Default)]
pub(in crate::models::billiards) struct Components {
    /// By slot: the union-find's parent ([`SlotSets`]).
    ///
    /// [`SlotSets`]: super::label::SlotSets
    pub(super) parent: Vec<u32>,
    /// By part of [`Components::label_components`]: the pairs that reach a
    /// later part's slots.
    pub(super) crossing: Vec<Vec<(u32, u32)>>,
    /// By part: the slots whose label waits for a root in an earlier part
    /// (their components' discs that are placed after the parts').
    pub(super) pending: Vec<Vec<u32>>,
    /// By slot: the disc's component, or `NONE`.
    pub(super) label: Vec<u32>,
    /// By slot: the disc's position in `members` (its place in its component's
    /// block plus the component's first position).
    pub(super) local: Vec<u32>,
    pub(super) member_start: Vec<u32>,
    /// Each component's discs (vector positions), in slot order, component by
    /// component (up to `member_start[components]`; room for all the discs).
    pub(super) members: Vec<u32>,
    pub(super) counts: Vec<u32>,
    /// Each component's first pair (in `staged` and in `pairs`).
    pub(super) pair_start: Vec<u32>,
    /// The pairs by component, in the order found.
    pub(super) staged: Vec<Staged>,
    /// By member position: one more than the level of the disc's latest pair.
    pub(super) depth: Vec<u32>,
    /// Each component's pairs in canonical order: `key << 32 | position`
    /// (within the component's range of `staged`).
    pub(super) order: Vec<u128>,
    /// The bucket offsets of a large component's sorts (scratch).
    pub(super) sort_start: Vec<u32>,
    /// By pair, in canonical order: its level.
    pub(super) level: Vec<u32>,
    /// Each component's number of levels.
    pub(super) levels: Vec<u32>,
    /// Component `c`'s level bounds (pair positions), `levels[c] + 1` of them
    /// from `pair_start[c] + c` (room for one more than its pairs).
    pub(super) run_bounds: Vec<u32>,
    pub(super) pairs: LocalPairs,
    pub(super) wall_start: Vec<u32>,
    pub(super) walls: Vec<(u32, Walls)>,
    pub(super) discs: Vec<LocalDisc>,
}

pub(super) const NONE: u32 = u32::MAX;

impl Components {
    /// Runs the canonical loop in every component, in parallel, and writes the new
    /// velocities back. Returns the largest sweep count (at least 1), or,
    /// of the components that had not settled within `max_sweeps`, the one with
    /// the smallest disc: that disc and the component's size.
    pub(in crate::models::billiards) fn resolve(
        &mut self,
        v: &mut [[f64; 2]],
        max_sweeps: u64,
        threads: &Threads,
    ) -> Result<u64, (usize, usize)> {
        let components = self.levels.len();
        let read: &[[f64; 2]] = v;
        let member_start = &self.member_start;
        let members = &self.members[..member_start[components] as usize];
        fill_in_parts(&mut self.discs, members.len(), Some(threads), |range| {
            members[range].iter().map(|&k| LocalDisc {
                v: read[k as usize],
            })
        });
        let (pairs, walls, wall_start) = (&self.pairs, &self.walls, &self.wall_start);
        let (pair_start, levels, run_bounds) = (&self.pair_start, &self.levels, &self.run_bounds);
        // (largest sweep count, (smallest disc, size) of the components that did
        // not settle)
        let shared = DisjointSlice::new(&mut self.discs);
        let (sweeps, failed) = threads.install(|| {
            (0..components)
                .into_par_iter()
                .map(|c| {
                    let range = member_start[c] as usize..member_start[c + 1] as usize;
                    // SAFETY: the components' member ranges are disjoint
                    let block = unsafe { shared.range(range.clone()) };
                    let runs = runs_of(pair_start, levels, run_bounds, c);
                    let component = Component {
                        walls: &walls[wall_start[c] as usize..wall_start[c + 1] as usize],
                        pairs: pairs.columns(runs[0] as usize..runs[runs.len() - 1] as usize),
                        runs,
                    };
                    match component.settle(block, max_sweeps) {
                        Some(sweeps) => (sweeps, (NONE, 0)),
                        None => {
                            let first = members[range.clone()].iter().min().copied();
                            (0, (first.unwrap_or(0), range.len()))
                        }
                    }
                })
                .reduce(|| (1, (NONE, 0)), |a, b| (a.0.max(b.0), a.1.min(b.1)))
        });
        let discs = &self.discs;
        // SAFETY: a disc is a member of one component, once
        unsafe {
            scatter_in_parts(v, members.len(), Some(threads), |slots| {
                members[slots.clone()]
                    .iter()
                    .zip(&discs[slots])
                    .map(|(&k, disc)| (k as usize, disc.v))
            });
        }
        match failed {
            (NONE, _) => Ok(sweeps),
            (first, size) => Err((first as usize, size)),
        }
    }
}

/// Component `c`'s level bounds in `run_bounds` (see [`Components`]):
/// `levels[c] + 1` pair positions, level `k`'s pairs from the `k`-th to the next.
pub(super) fn runs_of<'a>(
    pair_start: &[u32],
    levels: &[u32],
    run_bounds: &'a [u32],
    c: usize,
) -> &'a [u32] {
    let first = pair_start[c] as usize + c;
    &run_bounds[first..=first + levels[c] as usize]
}

/// One component's pairs: the columns of [`LocalPairs`] over its range.
#[derive(Clone, Copy)]
struct PairColumns<'a> {
    a: &'a [u32],
    b: &'a [u32],
    dx: &'a [f64],
    dy: &'a [f64],
    q: &'a [f64],
}

impl LocalPairs {
    /// The columns of the pairs in `range`.
    #[inline]
    fn columns(&self, range: std::ops::Range<usize>) -> PairColumns<'_> {
        PairColumns {
            a: &self.a[range.clone()],
            b: &self.b[range.clone()],
            dx: &self.dx[range.clone()],
            dy: &self.dy[range.clone()],
            q: &self.q[range],
        }
    }
}

/// One component's walls (ascending) and its pairs, run by run.
struct Component<'a> {
    walls: &'a [(u32, Walls)],
    pairs: PairColumns<'a>,
    /// `runs[k] - runs[0]..runs[k + 1] - runs[0]`: the pairs of level `k`.
    runs: &'a [u32],
}

impl Component<'_> {
    /// The canonical loop on this component: sweeps until one changes nothing; the
    /// number of sweeps (the last included), or `None` past `max_sweeps`.
    fn settle(&self, block: &mut [LocalDisc], max_sweeps: u64) -> Option<u64> {
        let p = self.pairs;
        // the lanes below index `block` unchecked
        assert!(p.a.iter().chain(p.b).all(|&k| (k as usize) < block.len()));
        let mut sweeps = 0;
        loop {
            sweeps += 1;
            if sweeps > max_sweeps {
                return None;
            }
            let mut changed = false;
            for (k, w) in self.walls {
                let v = &mut block[*k as usize].v;
                if w.collides(v) {
                    w.resolve(v);
                    changed = true;
                }
            }
            let first = self.runs[0];
            for run in self.runs.windows(2) {
                let (start, end) = ((run[0] - first) as usize, (run[1] - first) as usize);
                let four = start + (end - start) / 4 * 4;
                for lanes in (start..four).step_by(4) {
                    let lanes = lanes..lanes + 4;
                    let a: [u32; 4] = p.a[lanes.clone()].try_into().unwrap();
                    let b: [u32; 4] = p.b[lanes.clone()].try_into().unwrap();
                    let separation =
                        [p.dx, p.dy, p.q].map(|column| F64x4::load(&column[lanes.clone()]));
                    // SAFETY: every index was checked against `block.len()` above
                    let velocity = |k: u32| unsafe { block.get_unchecked(k as usize).v };
                    let (mut va, mut vb) = (a.map(velocity), b.map(velocity));
                    changed |= collide_four(separation, &mut va, &mut vb);
                    for l in 0..4 {
                        // SAFETY: as above
                        unsafe {
                            block.get_unchecked_mut(a[l] as usize).v = va[l];
                            block.get_unchecked_mut(b[l] as usize).v = vb[l];
                        }
                    }
                }
                for pair in four..end {
                    let (a, b) = (p.a[pair] as usize, p.b[pair] as usize);
                    let sep = Separation {
                        dx: p.dx[pair],
                        dy: p.dy[pair],
                        q: p.q[pair],
                    };
                    let (mut va, mut vb) = (block[a].v, block[b].v);
                    if sep.collide(&mut va, &mut vb) {
                        block[a].v = va;
                        block[b].v = vb;
                        changed = true;
                    }
                }
            }
            if !changed {
                return Some(sweeps);
            }
        }
    }
}
