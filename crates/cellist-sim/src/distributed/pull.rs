//! Outputs of a model spread over the ranks without the whole state in one
//! place: rank 0 pulls the particles a block of ids at a time, in id order,
//! while the other ranks serve its asks.
//!
//! ```text
//! rank 0                                  ranks 1 .. P-1
//! for each block [a, a + w) of ids:       loop:
//!   broadcast Rows(a, a + w)       --->     broadcast (receive the ask)
//!   gather every rank's rows       <---     gather own rows with a <= id < a + w
//!   sort by id, visit                       (Done: stop)
//! broadcast Done (after the outputs)
//! ```
//!
//! Ids span `[first, last]` over all ranks; a block is `w = ceil((last -
//! first + 1) BLOCK_ROWS / N)` ids wide, so that blocks hold about
//! [`BLOCK_ROWS`] particles when the ids are dense (LAMMPS's 1..N). Rank 0
//! holds one block of rows at a time, never the whole state.

use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::traits::*;

/// Particles per block, on average over dense ids: about 0.5 MB of rows.
pub const BLOCK_ROWS: usize = 4096;

/// An ask of rank 0, broadcast to every rank: `[kind, first id, end id]`.
const ROWS: u64 = 1;
const DONE: u64 = 2;

/// The ids over all ranks: the smallest, the largest and how many.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IdSpan {
    /// The smallest id.
    pub first: u64,
    /// The largest id.
    pub last: u64,
    /// The particles over all ranks.
    pub count: usize,
}

impl IdSpan {
    /// The span of every rank's `ids` (collective).
    pub fn of<C: Communicator>(world: &C, ids: &[u64]) -> IdSpan {
        let first = ids.iter().copied().min().unwrap_or(u64::MAX);
        let last = ids.iter().copied().max().unwrap_or(0);
        // the smallest first id as the largest of u64::MAX - first
        let mine = [u64::MAX - first, last];
        let mut most = [0u64; 2];
        world.all_reduce_into(&mine[..], &mut most[..], SystemOperation::max());
        let mut count = 0u64;
        world.all_reduce_into(&(ids.len() as u64), &mut count, SystemOperation::sum());
        IdSpan {
            first: u64::MAX - most[0],
            last: most[1],
            count: count as usize,
        }
    }

    /// The blocks of ids in ascending order, `[a, b)` each, about
    /// [`BLOCK_ROWS`] particles wide when the ids are dense.
    fn blocks(&self) -> impl Iterator<Item = (u64, u64)> {
        let (first, last) = (self.first, self.last);
        let span = if self.count == 0 {
            0
        } else {
            (last - first).saturating_add(1)
        };
        let width = span
            .div_ceil(self.count.div_ceil(BLOCK_ROWS).max(1) as u64)
            .max(1);
        (0..span.div_ceil(width)).map(move |b| {
            let a = first + b * width;
            (a, a.saturating_add(width).min(last.saturating_add(1)))
        })
    }
}

/// This rank's particles with ids in `[a, b)`, in ascending id, as `ids` and
/// `width` numbers each in `values` (both cleared first).
pub trait OwnRows {
    /// Numbers per particle.
    fn width(&self) -> usize;
    /// Fills `ids` and `values` with the rows of ids `a <= id < b`.
    fn rows(&self, a: u64, b: u64, ids: &mut Vec<u64>, values: &mut Vec<f64>);
}

/// On rank 0: every rank's rows ([`OwnRows`]) a block of ids at a time, in
/// ascending id, handed to `visit(ids, values)` until it returns false. The
/// other ranks must be serving ([`serve_until_written`]); end with it.
pub fn pull<C: Communicator>(
    world: &C,
    span: IdSpan,
    own: &impl OwnRows,
    mut visit: impl FnMut(&[u64], &[f64]) -> bool,
) {
    let width = own.width();
    let (mut ids, mut values) = (Vec::new(), Vec::new());
    let (mut all_ids, mut all_values) = (Vec::new(), Vec::new());
    let mut order = Vec::new();
    let (mut sorted_ids, mut sorted_values) = (Vec::new(), Vec::new());
    for (a, b) in span.blocks() {
        let mut ask = [ROWS, a, b];
        world.process_at_rank(0).broadcast_into(&mut ask[..]);
        own.rows(a, b, &mut ids, &mut values);
        gather_rows(world, &ids, &values, width, &mut all_ids, &mut all_values);
        order.clear();
        order.extend(0..all_ids.len());
        order.sort_unstable_by_key(|&k| all_ids[k]);
        sorted_ids.clear();
        sorted_ids.extend(order.iter().map(|&k| all_ids[k]));
        sorted_values.clear();
        for &k in &order {
            sorted_values.extend_from_slice(&all_values[k * width..(k + 1) * width]);
        }
        if !visit(&sorted_ids, &sorted_values) {
            return;
        }
    }
}

/// On rank 0: tells the ranks in [`serve`] that the outputs are written.
fn release<C: Communicator>(world: &C) {
    let mut ask = [DONE, 0, 0];
    world.process_at_rank(0).broadcast_into(&mut ask[..]);
}

/// On the ranks other than 0: answers rank 0's asks for rows ([`pull`])
/// until it [`release`]s them.
fn serve<C: Communicator>(world: &C, own: &impl OwnRows) {
    let (mut ids, mut values) = (Vec::new(), Vec::new());
    loop {
        let mut ask = [0u64; 3];
        world.process_at_rank(0).broadcast_into(&mut ask[..]);
        if ask[0] != ROWS {
            return;
        }
        own.rows(ask[1], ask[2], &mut ids, &mut values);
        let root = world.process_at_rank(0);
        root.gather_into(&(ids.len() as u64));
        root.gather_varcount_into(&ids[..]);
        root.gather_varcount_into(&values[..]);
    }
}

/// After rank 0's outputs: on rank 0, tells the other ranks that they are
/// written; on the others, serves rank 0's pulls of `own` ([`pull`]) until
/// then.
pub fn serve_until_written<C: Communicator>(world: &C, own: &impl OwnRows) {
    if world.rank() == 0 {
        release(world);
    } else {
        serve(world, own);
    }
}

/// On rank 0: every rank's `ids` and rows of `width` numbers, rank after
/// rank, into `all_ids` and `all_values`.
fn gather_rows<C: Communicator>(
    world: &C,
    ids: &[u64],
    values: &[f64],
    width: usize,
    all_ids: &mut Vec<u64>,
    all_values: &mut Vec<f64>,
) {
    let root = world.process_at_rank(0);
    let mut counts = vec![0u64; world.size() as usize];
    root.gather_into_root(&(ids.len() as u64), &mut counts[..]);
    let total: u64 = counts.iter().sum();
    let offsets = |scale: u64| {
        super::layout(
            &counts
                .iter()
                .map(|&c| (c * scale) as usize)
                .collect::<Vec<_>>(),
        )
    };
    all_ids.resize(total as usize, 0);
    let (sizes, starts) = offsets(1);
    root.gather_varcount_into_root(ids, &mut PartitionMut::new(&mut all_ids[..], sizes, starts));
    all_values.resize(total as usize * width, 0.0);
    let (sizes, starts) = offsets(width as u64);
    root.gather_varcount_into_root(
        values,
        &mut PartitionMut::new(&mut all_values[..], sizes, starts),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blocks(first: u64, last: u64, count: usize) -> Vec<(u64, u64)> {
        IdSpan { first, last, count }.blocks().collect()
    }

    /// The blocks cover `[first, last]` once, in order, each about
    /// BLOCK_ROWS ids wide for dense ids.
    #[test]
    fn blocks_cover_the_span_once() {
        for (first, last, count) in [
            (1, 1, 1),
            (1, 100_000, 100_000),
            (7, 7 + 3 * BLOCK_ROWS as u64, 3 * BLOCK_ROWS + 1),
            (0, u64::MAX - 1, 5),
            (1, 1_000_000_000, 3),
        ] {
            let b = blocks(first, last, count);
            assert_eq!(b[0].0, first);
            assert_eq!(b.last().unwrap().1, last + 1);
            for pair in b.windows(2) {
                assert_eq!(pair[0].1, pair[1].0);
            }
            assert!(b.iter().all(|(a, e)| a < e));
            assert!(b.len() <= count.div_ceil(BLOCK_ROWS).max(1));
        }
        assert!(blocks(u64::MAX, 0, 0).is_empty());
    }
}
