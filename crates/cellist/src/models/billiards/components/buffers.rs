//! The columns the components of a step live in, kept between steps: the
//! disc and pair numbers of the labelling and the grouping, each component's
//! pairs by level, its walls and its block of velocities.

use crate::models::billiards::rules::{Separation, Walls};

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

/// A pair of slots `a`, `b` as found, with its canonical key `(number[a],
/// number[b])` in one integer.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Staged {
    pub(super) key: u64,
    pub(super) a: u32,
    pub(super) b: u32,
    pub(super) sep: Separation,
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
