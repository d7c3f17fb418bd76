//! The resolution: the canonical loop run on every component at once, each on
//! its own block of velocities, its pairs level by level, four disjoint pairs
//! at a time in SIMD lanes; then the velocities written back.

use super::buffers::{Components, LocalDisc, LocalPairs, NONE};
use crate::models::billiards::rules::{collide_four, Separation, Walls};
use crate::simd::F64x4;
use crate::threads::{fill_in_parts, scatter_in_parts, DisjointSlice, Threads};
use rayon::prelude::*;

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
