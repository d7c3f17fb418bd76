//! Barnes-Hut: an octree over the particles in Morton order, with each node's
//! mass, centre of mass and (optionally) traceless quadrupole, walked once per
//! group (the largest nodes of at most `group_size` nearby particles) to build
//! the lists that the group's particles then sum in straight-line SIMD code.
//!
//! A node of side `l` whose centre of mass lies `delta` from its cube's centre is
//! accepted for a group when its centre of mass is farther than
//! `l / theta + delta` from the group's bounding box and it holds none of the
//! group's particles; otherwise it is opened, and an opened leaf gives its
//! particles. Its
//! field at `x`, with `r = x - x_com`, `s^2 = |r|^2 + eps^2`, is
//!
//! `phi = -G (M/s + (r.Q.r) / (2 s^5))`,
//! `acc = G (-M r / s^3 + Q r / s^5 - 5/2 (r.Q.r) r / s^7)`,
//!
//! with `Q_ab = sum_p m_p (3 y_a y_b - |y|^2 delta_ab)`, `y = x_p - x_com`. With
//! repulsion the monopole carries its factors `(1 - a^4/s^4)` and
//! `(1 - a^4/(5 s^4))` as particles do (see [`GravityLaw`]).
//!
//! The walk gathers (every group writes only its own particles) in parallel, and
//! the lists and sums run in an order fixed by the tree, so 1 and N threads give
//! the same bits.

mod build;
mod walk;

use super::{FieldOut, Sources};
use crate::interactions::GravityLaw;
use crate::threads::{DisjointSlice, Threads};
use build::Octree;
use rayon::prelude::*;
use std::sync::Mutex;
use walk::{Lists, Moments};

/// The tree's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeParams {
    /// The opening angle, in `(0, 1.2]`: smaller is more accurate and slower.
    pub theta: f64,
    /// Whether nodes carry quadrupoles (more accurate per node) or monopoles only.
    pub quadrupole: bool,
    /// Most particles in a leaf: opened leaves give their particles.
    pub leaf_size: usize,
    /// Most particles in a walk group: the particles that share one walk and
    /// its interaction lists.
    pub group_size: usize,
}

impl Default for TreeParams {
    fn default() -> Self {
        TreeParams {
            theta: 0.5,
            quadrupole: true,
            leaf_size: 16,
            group_size: 128,
        }
    }
}

impl TreeParams {
    /// Checks the ranges: `theta` in `(0, 1.2]`, `leaf_size` and `group_size` in
    /// `1..=256`.
    pub fn check(&self) -> Result<(), String> {
        if !(self.theta > 0.0 && self.theta <= 1.2) {
            return Err(format!("theta must be in (0, 1.2], got {}", self.theta));
        }
        if !(1..=256).contains(&self.leaf_size) {
            return Err(format!(
                "leaf_size must be in 1..=256, got {}",
                self.leaf_size
            ));
        }
        if !(1..=256).contains(&self.group_size) {
            return Err(format!(
                "group_size must be in 1..=256, got {}",
                self.group_size
            ));
        }
        Ok(())
    }
}

/// The Barnes-Hut solver: the tree, its moments and the per-thread scratch,
/// kept between evaluations.
#[derive(Debug)]
pub struct BarnesHut {
    law: GravityLaw,
    params: TreeParams,
    tree: Octree,
    moments: Moments,
    sorted_acc: Vec<[f64; 4]>,
    scratch: Vec<Mutex<Lists>>,
    interactions: (u64, u64),
}

impl BarnesHut {
    /// A solver for `law` with `params` (checked).
    pub fn new(law: GravityLaw, params: TreeParams) -> Result<Self, String> {
        params.check()?;
        Ok(BarnesHut {
            law,
            params,
            tree: Octree::default(),
            moments: Moments::default(),
            sorted_acc: Vec::new(),
            scratch: Vec::new(),
            interactions: (0, 0),
        })
    }

    /// `(node, particle)` interactions of the last evaluation.
    pub fn interactions(&self) -> (u64, u64) {
        self.interactions
    }

    /// Fills `out` with the tree's accelerations and potentials of `sources`.
    pub fn compute(&mut self, sources: &Sources, out: FieldOut, threads: &Threads) {
        let n = sources.mass.len();
        let sizes = build::Sizes {
            leaf: self.params.leaf_size,
            group: self.params.group_size,
        };
        self.tree.build(sources.position, sizes, threads);
        self.moments
            .compute(&self.tree, sources, &self.params, threads);
        self.sorted_acc.resize(n, [0.0; 4]);
        while self.scratch.len() < threads.count() {
            self.scratch.push(Mutex::new(Lists::default()));
        }
        let shared = DisjointSlice::new(&mut self.sorted_acc);
        let (tree, moments, scratch) = (&self.tree, &self.moments, &self.scratch);
        let kernel = super::direct::Kernel::new(&self.law);
        let quadrupole = self.params.quadrupole;
        let counts = threads.install(|| {
            tree.groups
                .par_iter()
                .map(|&group| {
                    let thread = rayon::current_thread_index().unwrap_or(0);
                    let mut lists = scratch[thread].lock().expect("scratch of a panicked walk");
                    let node = &tree.nodes[group as usize];
                    // SAFETY: groups hold disjoint ranges of the sorted particles.
                    let target = unsafe { shared.range(node.start as usize..node.end as usize) };
                    lists.gather(tree, moments, group as usize, quadrupole);
                    if self.law.has_repulsion() {
                        lists.evaluate::<true>(&kernel, moments, node.start as usize, target);
                    } else {
                        lists.evaluate::<false>(&kernel, moments, node.start as usize, target);
                    }
                    lists.counts(target.len())
                })
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
        });
        self.interactions = counts;
        let g = self.law.g();
        for (s, &i) in self.tree.order.iter().enumerate() {
            let v = self.sorted_acc[s];
            out.acc[i as usize] = [g * v[0], g * v[1], g * v[2]];
            out.phi[i as usize] = -g * v[3];
        }
    }
}
