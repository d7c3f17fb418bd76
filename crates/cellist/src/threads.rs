//! Explicit parallelism: a thread pool passed to every parallel routine, never a
//! hidden global, and helpers whose results do not depend on the thread count.

use rayon::prelude::*;
use std::mem::MaybeUninit;

/// A pool of worker threads for one run.
pub struct Threads {
    pool: rayon::ThreadPool,
}

impl std::fmt::Debug for Threads {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Threads({})", self.count())
    }
}

impl Threads {
    /// A pool of `count` threads (`count >= 1`).
    pub fn new(count: usize) -> Result<Self, rayon::ThreadPoolBuildError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(count.max(1))
            .thread_name(|k| format!("cellist-{k}"))
            .build()?;
        Ok(Threads { pool })
    }

    /// A single-threaded pool (still runs the parallel code paths).
    pub fn single() -> Self {
        Self::new(1).expect("a one-thread pool can always be built")
    }

    /// Number of threads.
    pub fn count(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Runs `op` inside the pool: rayon's parallel iterators in it use these threads.
    pub fn install<R: Send>(&self, op: impl FnOnce() -> R + Send) -> R {
        self.pool.install(op)
    }

    /// Splits `0..n` into chunks of a size fixed by `n` alone (not by the thread
    /// count), so that per-chunk results concatenated in order are the same for any
    /// number of threads.
    pub fn chunks(n: usize) -> impl IndexedParallelIterator<Item = std::ops::Range<usize>> {
        const MIN_CHUNK: usize = 16;
        const MAX_CHUNKS: usize = 1024;
        let size = n.div_ceil(MAX_CHUNKS).max(MIN_CHUNK);
        (0..n.div_ceil(size))
            .into_par_iter()
            .map(move |k| k * size..((k + 1) * size).min(n))
    }
}

/// Where one task of [`collect_in_order`] appends: its stretch of the result,
/// then, past the stretch's estimated length, a spill vector of its own.
pub struct Stretch<'a, T> {
    room: &'a mut [MaybeUninit<T>],
    len: usize,
    spill: Vec<T>,
}

impl<T> Stretch<'_, T> {
    /// Appends `value` after the task's earlier values.
    #[inline(always)]
    pub fn push(&mut self, value: T) {
        match self.room.get_mut(self.len) {
            Some(slot) => {
                slot.write(value);
                self.len += 1;
            }
            None => self.spill.push(value),
        }
    }

    /// Appends `value` if `keep`, without a branch on `keep` while the stretch
    /// has room (the value is written either way; a rejected one is
    /// overwritten by the next).
    #[inline(always)]
    pub fn push_if(&mut self, value: T, keep: bool) {
        match self.room.get_mut(self.len) {
            Some(slot) => {
                slot.write(value);
                self.len += usize::from(keep);
            }
            None if keep => self.spill.push(value),
            None => {}
        }
    }
}

/// One vector filled by `estimates.len()` tasks in parallel, task `k` appending
/// through `fill(k, stretch)`: the values of task 0, then task 1's, and so on,
/// whatever the thread count. Task `k` writes straight into its own stretch of
/// the result, `estimates[k]` long, starting after the estimates of the tasks
/// before it: each value is written once, by the thread that computed it, which
/// also takes the page faults of its stretch. The stretches are then closed up
/// (each moved down behind the one before). A task that outgrows its estimate
/// spills the rest into a vector of its own, and the result is then assembled
/// by one more copy.
pub fn collect_in_order<T: Copy + Send + Sync>(
    estimates: &[usize],
    threads: &Threads,
    fill: impl Fn(usize, &mut Stretch<T>) + Sync,
) -> Vec<T> {
    let mut out = Vec::new();
    collect_in_order_into(&mut out, estimates, threads, fill);
    out
}

/// [`collect_in_order`] into `out`, whose contents are replaced; its memory is
/// reused when it has room for the estimates.
pub fn collect_in_order_into<T: Copy + Send + Sync>(
    out: &mut Vec<T>,
    estimates: &[usize],
    threads: &Threads,
    fill: impl Fn(usize, &mut Stretch<T>) + Sync,
) {
    let total: usize = estimates.iter().sum();
    out.clear();
    if out.capacity() < total {
        *out = crate::memory::large_vec::<T>(total);
    }
    let mut rooms = Vec::with_capacity(estimates.len());
    let mut rest = &mut out.spare_capacity_mut()[..total];
    for &estimate in estimates {
        let (head, tail) = rest.split_at_mut(estimate);
        rooms.push(head);
        rest = tail;
    }
    let run = |(k, room): (usize, &mut [MaybeUninit<T>])| {
        let mut stretch = Stretch {
            room,
            len: 0,
            spill: Vec::new(),
        };
        fill(k, &mut stretch);
        (stretch.len, stretch.spill)
    };
    let done: Vec<(usize, Vec<T>)> = if rooms.len() == 1 {
        rooms.into_iter().enumerate().map(run).collect()
    } else {
        threads.install(|| rooms.into_par_iter().enumerate().map(run).collect())
    };
    let starts = exclusive_sums(estimates);
    let base = out.as_mut_ptr();
    if done.iter().all(|(_, spill)| spill.is_empty()) {
        let mut end = 0;
        for (&start, &(len, _)) in starts.iter().zip(&done) {
            if start != end {
                // SAFETY: `base[start..start + len]` was written by its task, and
                // `end <= start` (every earlier task wrote at most its estimate),
                // so both ranges lie in the allocation; `copy` allows them to
                // overlap.
                unsafe { std::ptr::copy(base.add(start), base.add(end), len) };
            }
            end += len;
        }
        // SAFETY: `out[..end]` holds the stretches, closed up above.
        unsafe { out.set_len(end) };
        return;
    }
    let length = done.iter().map(|(len, spill)| len + spill.len()).sum();
    let mut whole = crate::memory::large_vec(length);
    for (&start, (len, spill)) in starts.iter().zip(&done) {
        // SAFETY: `base[start..start + len]` was written by its task.
        whole.extend_from_slice(unsafe { std::slice::from_raw_parts(base.add(start), *len) });
        whole.extend_from_slice(spill);
    }
    *out = whole;
}

/// The index ranges of `n` items split into `parts` nearly equal, consecutive
/// pieces (at least one piece).
pub fn part_ranges(n: usize, parts: usize) -> Vec<std::ops::Range<usize>> {
    let parts = parts.max(1);
    (0..parts)
        .map(|p| n * p / parts..n * (p + 1) / parts)
        .collect()
}

/// The exclusive prefix sums of `values`: `0, v_0, v_0 + v_1, ...`, one per
/// value (where each part's share of one result begins).
pub fn exclusive_sums<T: Copy + Default + std::ops::Add<Output = T>>(values: &[T]) -> Vec<T> {
    values
        .iter()
        .scan(T::default(), |next, &value| {
            let first = *next;
            *next = first + value;
            Some(first)
        })
        .collect()
}

/// `f(p)` for every part `p` in `0..parts`, in parallel on `threads` (in this
/// thread without them, or with one part), results in part order.
pub fn map_parts<R: Send>(
    threads: Option<&Threads>,
    parts: usize,
    f: impl Fn(usize) -> R + Sync + Send,
) -> Vec<R> {
    match threads {
        Some(pool) if parts > 1 => pool.install(|| (0..parts).into_par_iter().map(f).collect()),
        _ => (0..parts).map(f).collect(),
    }
}

/// The number of parts a pass over data is split into: one per thread.
pub fn parts_for(threads: Option<&Threads>) -> usize {
    threads.map_or(1, Threads::count)
}

/// Replaces the contents of `out` by `value(0), ..., value(n - 1)`, computed in
/// parts on `threads`; each value is written once, by the thread that computed
/// it. The result does not depend on the thread count.
pub fn fill_indexed<T: Copy + Send + Sync>(
    out: &mut Vec<T>,
    n: usize,
    threads: Option<&Threads>,
    value: impl Fn(usize) -> T + Sync + Send,
) {
    fill_in_parts(out, n, threads, |range| range.map(&value));
}

/// [`fill_indexed`] with each part's values given as one iterator:
/// `values(range)` yields the values of the indices `range`, in order (callers
/// that zip slices over the range need no bound check per index). Panics if a
/// part yields fewer values than its range holds; extra values are ignored.
pub fn fill_in_parts<T: Copy + Send + Sync, I: Iterator<Item = T>>(
    out: &mut Vec<T>,
    n: usize,
    threads: Option<&Threads>,
    values: impl Fn(std::ops::Range<usize>) -> I + Sync + Send,
) {
    out.clear();
    out.reserve(n);
    let ranges = part_ranges(n, parts_for(threads));
    let room = DisjointSlice::new(&mut out.spare_capacity_mut()[..n]);
    map_parts(threads, ranges.len(), |p| {
        // SAFETY: the parts' ranges are disjoint
        let slots = unsafe { room.range(ranges[p].clone()) };
        let mut written = 0;
        for (slot, value) in slots.iter_mut().zip(values(ranges[p].clone())) {
            slot.write(value);
            written += 1;
        }
        assert_eq!(
            written,
            slots.len(),
            "fill_in_parts: a part yielded too few values"
        );
    });
    // SAFETY: the ranges cover 0..n, and every slot was written above (checked)
    unsafe { out.set_len(n) };
}

/// `out[k] = value` for every `(k, value)` that `writes(range)` yields, the
/// index range `0..n` split in parts on `threads` (in this thread without
/// them): a scatter through a permutation, each part's writes by one thread.
/// Panics if an index is outside `out`.
///
/// # Safety
/// No index `k` is yielded twice over all the parts (the parts' writes run at
/// once on different threads).
pub unsafe fn scatter_in_parts<T: Send, I: Iterator<Item = (usize, T)>>(
    out: &mut [T],
    n: usize,
    threads: Option<&Threads>,
    writes: impl Fn(std::ops::Range<usize>) -> I + Sync + Send,
) {
    let ranges = part_ranges(n, parts_for(threads));
    let shared = DisjointSlice::new(out);
    map_parts(threads, ranges.len(), |p| {
        for (k, value) in writes(ranges[p].clone()) {
            // SAFETY: no index is written twice (the caller's promise)
            *unsafe { shared.get(k) } = value;
        }
    });
}

/// A stable counting sort of the indices `0..keys.len()` by key (`keys[i] <
/// buckets`), in parts on `threads` ([`counting_sort_with`]): `start` gets the
/// `buckets + 1` bucket offsets, `order` the indices bucket by bucket, ascending
/// within a bucket. The result is the same for any thread count.
pub fn counting_sort(
    keys: &[u32],
    buckets: usize,
    threads: Option<&Threads>,
    start: &mut Vec<u32>,
    order: &mut Vec<u32>,
    counts: &mut Vec<u32>,
) {
    let n = keys.len();
    order.clear();
    order.reserve(n);
    let slots = DisjointSlice::new(&mut order.spare_capacity_mut()[..n]);
    // SAFETY: the keys are a slice, the same on both passes
    unsafe {
        counting_sort_with(
            n,
            |i| keys[i],
            buckets,
            threads,
            start,
            counts,
            |i, slot| {
                // SAFETY: every slot is given to one index, below n
                slots.get_unchecked(slot).write(i as u32);
            },
        );
    }
    // SAFETY: the slots given out are exactly 0..n, each once
    unsafe { order.set_len(n) };
}

/// How many counts per item a counting sort may keep (parts x buckets): with
/// many buckets per item it splits into fewer parts.
const COUNTS_PER_ITEM: usize = 8;

/// A stable counting sort of `0..n` by `key(i)` (`key(i) < buckets`), in parts
/// on `threads`: `start` gets the `buckets + 1` bucket offsets (exclusive prefix
/// sums of the counts), and `place(i, slot)` is called once for every index `i`,
/// with the slot the sort gives it (bucket by bucket, ascending `i` within a
/// bucket), so that callers move their own data into place. `counts` is scratch.
/// The result is the same for any thread count (see [`counting_sort_parts`]).
/// Every slot is below `n` (checked once per index, so `place` may write
/// unchecked into columns of `n` elements); calls for different indices may run
/// on different threads at once; each slot is given once.
///
/// # Safety
/// `key` is called twice per index and must return the same value both times
/// (as [`counting_sort_parts`]).
pub unsafe fn counting_sort_with(
    n: usize,
    key: impl Fn(usize) -> u32 + Sync + Send,
    buckets: usize,
    threads: Option<&Threads>,
    start: &mut Vec<u32>,
    counts: &mut Vec<u32>,
    place: impl Fn(usize, usize) + Sync + Send,
) {
    let ranges = part_ranges(n, sort_parts(n, buckets, threads));
    // SAFETY: a part's indices are the same range both times; `key` is the
    // caller's promise
    unsafe {
        counting_sort_parts(
            ranges.len(),
            |p| ranges[p].clone(),
            |&i| key(i),
            buckets,
            threads,
            start,
            counts,
            place,
        );
    }
}

/// How many parts a counting sort of `n` items into `buckets` is split into:
/// one per thread, but few enough that the parts x buckets counts (each part
/// zeroes its row; the offsets are summed in blocks of buckets) stay within a
/// few (8) per item, which bounds their memory and the work of summing them.
pub fn sort_parts(n: usize, buckets: usize, threads: Option<&Threads>) -> usize {
    parts_for(threads).min(most_sort_parts(n, buckets))
}

/// The most parts a counting sort of `n` items into `buckets` may have, so
/// that its parts x buckets counts stay within a few (8) per item (at least
/// one part).
pub fn most_sort_parts(n: usize, buckets: usize) -> usize {
    (COUNTS_PER_ITEM * n / buckets.max(1)).max(1)
}

/// The stable counting sort under [`counting_sort_with`], of items given in
/// `parts` consecutive parts, `items(p)` listing part `p`'s in order: items that
/// already lie in pieces (the rows of a parallel search) are sorted where they
/// are, without first being gathered into one array. Part `p` counts its own
/// items into its row of `counts`; bucket `c`'s slots for part `p` then begin
/// at `start[c]` plus the counts of `c` in the parts before `p`, so every part
/// places into slots of its own, and the slots depend only on the items' order
/// and keys, not on how they are split into parts (the one-part prefix sum is
/// the same sum in a plainer loop). `place(item, slot)` is called once per item,
/// with a slot below the number of items (checked); calls for different items
/// may run on different threads at once.
///
/// # Safety
/// `items(p)` is called twice per part (to count, then to place) and must yield
/// the same items in the same order both times, and `key` must give an item the
/// same bucket both times. Otherwise two items may be given one slot and some
/// slots none: callers that write every slot and then set a length would expose
/// uninitialised memory.
#[allow(clippy::too_many_arguments)]
pub unsafe fn counting_sort_parts<I, It: Iterator<Item = I>>(
    parts: usize,
    items: impl Fn(usize) -> It + Sync + Send,
    key: impl Fn(&I) -> u32 + Sync + Send,
    buckets: usize,
    threads: Option<&Threads>,
    start: &mut Vec<u32>,
    counts: &mut Vec<u32>,
    place: impl Fn(I, usize) + Sync + Send,
) {
    // each part clears its own row (no serial pass over all the counts)
    counts.resize(parts * buckets, 0);
    let rows = DisjointSlice::new(counts);
    let sizes = map_parts(threads, parts, |p| {
        // SAFETY: each part counts into its own row
        let row = unsafe { rows.range(p * buckets..(p + 1) * buckets) };
        row.fill(0);
        let mut size = 0usize;
        for item in items(p) {
            row[key(&item) as usize] += 1;
            size += 1;
        }
        size
    });
    // (a bucket's count wraps only if the items reach 2^32: caught here, before
    // any count is used)
    let items_in_all: usize = sizes.iter().sum();
    assert!(
        items_in_all < u32::MAX as usize,
        "at most 2^32 - 1 items to sort"
    );
    // every entry of `start` is written below
    start.resize(buckets + 1, 0);
    let total = first_slots(counts, parts, buckets, start, threads) as usize;
    let cursors = DisjointSlice::new(counts);
    map_parts(threads, parts, |p| {
        // SAFETY: each part moves its own row of cursors; the slots a part
        // gives out are its own (see above)
        let cursor = unsafe { cursors.range(p * buckets..(p + 1) * buckets) };
        for item in items(p) {
            let slot = &mut cursor[key(&item) as usize];
            // the bound check callers' writes rely on (`place` may write
            // unchecked into columns as long as the items)
            assert!(
                (*slot as usize) < total,
                "counting sort: a key or an item changed between passes"
            );
            place(item, *slot as usize);
            *slot += 1;
        }
    });
}

/// Turns the counts of [`counting_sort_parts`] (row `p`: part `p`'s count per
/// bucket) into each part's first slot per bucket, bucket by bucket and part by
/// part (`slot(p, c) = sum of count(q, d) over d < c, and over d = c, q < p`),
/// and `start[c]` into bucket `c`'s first slot (`start[buckets]` the total,
/// which it returns). With several parts the buckets are cut into blocks, one
/// per part: the blocks sum their counts, then each, starting after the blocks
/// before it, writes its own slots (the same sums, in two passes).
fn first_slots(
    counts: &mut [u32],
    parts: usize,
    buckets: usize,
    start: &mut [u32],
    threads: Option<&Threads>,
) -> u32 {
    if parts == 1 {
        // one row: the plain exclusive prefix sum
        let mut at = 0u32;
        for (first, cursor) in start.iter_mut().zip(counts.iter_mut()) {
            *first = at;
            at += std::mem::replace(cursor, at);
        }
        start[buckets] = at;
        return at;
    }
    let blocks = part_ranges(buckets, parts);
    let totals = map_parts(threads, blocks.len(), |b| {
        let cell = |c: usize| (0..parts).map(|p| counts[p * buckets + c]).sum::<u32>();
        blocks[b].clone().map(cell).sum::<u32>()
    });
    let firsts = exclusive_sums(&totals);
    let (cursors, firsts_of_buckets) = (DisjointSlice::new(counts), DisjointSlice::new(start));
    map_parts(threads, blocks.len(), |b| {
        let mut at = firsts[b];
        for c in blocks[b].clone() {
            // SAFETY: bucket `c` (its first slot and its count in every row)
            // belongs to one block
            unsafe {
                *firsts_of_buckets.get(c) = at;
                for p in 0..parts {
                    let cursor = cursors.get(p * buckets + c);
                    at += std::mem::replace(cursor, at);
                }
            }
        }
    });
    let total = totals.iter().sum();
    start[buckets] = total;
    total
}

/// A mutable slice shared by threads that promise to touch disjoint elements.
///
/// This is how coloured passes write without locks or atomics: the colouring proves
/// that no two tasks of one pass reach the same particle.
pub struct DisjointSlice<'a, T> {
    ptr: *mut T,
    len: usize,
    _borrow: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: access is only through the unsafe methods (`get`, `get_unchecked`,
// `range`, `base`), whose callers guarantee disjoint indices across threads;
// T: Send makes moving the access to another thread sound.
unsafe impl<T: Send> Sync for DisjointSlice<'_, T> {}
unsafe impl<T: Send> Send for DisjointSlice<'_, T> {}

impl<'a, T> DisjointSlice<'a, T> {
    /// Shares `slice` for disjoint writes.
    pub fn new(slice: &'a mut [T]) -> Self {
        DisjointSlice {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _borrow: std::marker::PhantomData,
        }
    }

    /// Element `k`.
    ///
    /// # Safety
    /// No other thread, and no other live reference from this thread, may access
    /// element `k` while the returned reference lives.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn get(&self, k: usize) -> &mut T {
        assert!(k < self.len, "index {k} out of range {}", self.len);
        &mut *self.ptr.add(k)
    }

    /// Elements `range` as one slice.
    ///
    /// # Safety
    /// No other thread, and no other live reference from this thread, may access
    /// any element of `range` while the returned slice lives.
    #[inline]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn range(&self, range: std::ops::Range<usize>) -> &mut [T] {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "range {range:?} out of {}",
            self.len
        );
        std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len())
    }

    /// The first element's address, for callers that check their indices once
    /// against the length and then write through it under the same promise as
    /// [`DisjointSlice::get`].
    #[inline(always)]
    pub fn base(&self) -> *mut T {
        self.ptr
    }

    /// Element `k` without the bounds check.
    ///
    /// # Safety
    /// As [`DisjointSlice::get`], and `k` must be below the length.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn get_unchecked(&self, k: usize) -> &mut T {
        debug_assert!(k < self.len);
        &mut *self.ptr.add(k)
    }
}

/// The rounds of a round-robin tournament of `blocks` players (the circle method):
/// round 0 is every block with itself, then `m - 1` rounds (`m` = `blocks` rounded up
/// to even) in which every block meets a different one, so that every unordered
/// pair of blocks meets exactly once and no block plays twice in a round. Each pair
/// is `(smaller, larger)`.
pub fn tournament(blocks: usize) -> Vec<Vec<(usize, usize)>> {
    let mut rounds = vec![(0..blocks).map(|b| (b, b)).collect::<Vec<_>>()];
    let m = blocks + blocks % 2;
    for r in 0..m.saturating_sub(1) {
        let mut round = Vec::new();
        for k in 0..m / 2 {
            let (a, b) = if k == 0 {
                (r, m - 1)
            } else {
                ((r + k) % (m - 1), (r + m - 1 - k) % (m - 1))
            };
            // the odd one out meets the padding block: a bye
            if a < blocks && b < blocks {
                round.push((a.min(b), a.max(b)));
            }
        }
        rounds.push(round);
    }
    rounds
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_cover_the_range_in_order_independently_of_threads() {
        for n in [0, 1, 63, 64, 65, 100_000] {
            let one: Vec<_> = Threads::single().install(|| Threads::chunks(n).collect());
            let two: Vec<_> = Threads::new(2)
                .unwrap()
                .install(|| Threads::chunks(n).collect());
            assert_eq!(one, two);
            let flat: Vec<usize> = one.into_iter().flatten().collect();
            assert_eq!(flat, (0..n).collect::<Vec<_>>());
        }
    }

    proptest::proptest! {
        /// The parallel counting sort equals a stable sort by key, with its
        /// bucket offsets, `fill_indexed` and `fill_in_parts` equal a plain
        /// map, and `scatter_in_parts` a plain scatter, on no thread pool and
        /// on pools of 1 to 3 threads.
        #[test]
        fn counting_sort_is_a_stable_sort_by_key(
            keys in proptest::collection::vec(0u32..40, 0..500),
            extra in 0usize..5,
        ) {
            let buckets = 40 + extra;
            let mut want: Vec<u32> = (0..keys.len() as u32).collect();
            want.sort_by_key(|&i| keys[i as usize]);
            let want_start: Vec<u32> = (0..=buckets as u32)
                .map(|c| keys.iter().filter(|&&k| k < c).count() as u32)
                .collect();
            let pools: Vec<Threads> = (1..=3).map(|t| Threads::new(t).unwrap()).collect();
            let mut runs: Vec<Option<&Threads>> = vec![None];
            runs.extend(pools.iter().map(Some));
            for threads in runs {
                // stale buffers, as a sort kept between steps leaves them
                let (mut start, mut order) = (vec![7; 50], vec![9; 3]);
                let mut counts = vec![u32::MAX; 200];
                counting_sort(&keys, buckets, threads, &mut start, &mut order, &mut counts);
                proptest::prop_assert_eq!(&order, &want);
                proptest::prop_assert_eq!(&start, &want_start);
                let mut filled = vec![1.5];
                fill_indexed(&mut filled, keys.len(), threads, |k| keys[k] as f64 * 0.5);
                let direct: Vec<f64> = keys.iter().map(|&k| k as f64 * 0.5).collect();
                proptest::prop_assert_eq!(&filled, &direct);
                let mut zipped = vec![2.5; 3];
                fill_in_parts(&mut zipped, keys.len(), threads, |range| {
                    keys[range].iter().map(|&k| k as f64 * 0.5)
                });
                proptest::prop_assert_eq!(zipped, direct);
                // the sort's order is a permutation: scattering each rank to
                // its index gives the inverse permutation
                let mut rank_of = vec![u32::MAX; keys.len()];
                for (rank, &i) in want.iter().enumerate() {
                    rank_of[i as usize] = rank as u32;
                }
                let mut scattered = vec![u32::MAX; keys.len()];
                // SAFETY: `order` is a permutation, so no index comes twice
                unsafe {
                    scatter_in_parts(&mut scattered, order.len(), threads, |range| {
                        order[range.clone()].iter().map(|&i| i as usize).zip(range.map(|r| r as u32))
                    });
                }
                proptest::prop_assert_eq!(scattered, rank_of);
            }
        }

        /// Items sorted where they lie, in pieces (empty ones too) grouped
        /// into parts of any sizes, get the slots of the same items sorted in
        /// one array: the parts change nothing but the work's split.
        #[test]
        fn sorting_in_pieces_equals_sorting_one_array(
            pieces in proptest::collection::vec(proptest::collection::vec(0u32..30, 0..40), 0..12),
            cuts in proptest::collection::vec(0usize..13, 0..5),
            threads in 1usize..4,
            buckets in 1u32..31,
        ) {
            // fewer buckets than parts too
            let pieces: Vec<Vec<u32>> = pieces
                .iter()
                .map(|piece| piece.iter().map(|&key| key % buckets).collect())
                .collect();
            let keys: Vec<u32> = pieces.iter().flatten().copied().collect();
            let mut want: Vec<u32> = (0..keys.len() as u32).collect();
            want.sort_by_key(|&i| keys[i as usize]);
            let want_start: Vec<u32> = (0..=buckets)
                .map(|c| keys.iter().filter(|&&k| k < c).count() as u32)
                .collect();
            // the parts: consecutive runs of pieces between sorted cut points
            let mut bounds: Vec<usize> = cuts.iter().map(|&c| c.min(pieces.len())).collect();
            bounds.extend([0, pieces.len()]);
            bounds.sort_unstable();
            let parts: Vec<std::ops::Range<usize>> =
                bounds.windows(2).map(|w| w[0]..w[1]).collect();
            // each item carries its index in the flattened order
            let mut first = 0;
            let indexed: Vec<Vec<(usize, u32)>> = pieces
                .iter()
                .map(|piece| {
                    let run = piece.iter().enumerate().map(|(k, &key)| (first + k, key)).collect();
                    first += piece.len();
                    run
                })
                .collect();
            let pool = Threads::new(threads).unwrap();
            let mut order = vec![u32::MAX; keys.len()];
            let slots = DisjointSlice::new(&mut order);
            // the buffers of an earlier, larger sort: nothing of theirs may leak
            let (mut start, mut counts) = (vec![u32::MAX; 40], vec![u32::MAX; 300]);
            // SAFETY: every slot is given once
            let place = |item: &(usize, u32), slot| *unsafe { slots.get(slot) } = item.0 as u32;
            // SAFETY: the pieces do not change during the sort
            unsafe {
                counting_sort_parts(
                    parts.len(),
                    |p| indexed[parts[p].clone()].iter().flatten(),
                    |item| item.1,
                    buckets as usize,
                    Some(&pool),
                    &mut start,
                    &mut counts,
                    place,
                );
            }
            proptest::prop_assert_eq!(order, want);
            proptest::prop_assert_eq!(start, want_start);
        }

        /// Whatever the estimates (short, exact, long or zero) and the thread
        /// count, the tasks' values come out in task order, and values pushed
        /// with `push_if(_, false)` do not.
        #[test]
        fn collected_values_are_the_tasks_values_in_order(
            lengths in proptest::collection::vec(0usize..300, 1..7),
            slack in proptest::collection::vec(-50i64..50, 7),
            threads in 1usize..4,
        ) {
            let estimates: Vec<usize> = lengths
                .iter()
                .zip(&slack)
                .map(|(&l, &s)| (l as i64 + s).max(0) as usize)
                .collect();
            let value = |k: usize, v: usize| (k * 1000 + v) as u32;
            let pool = Threads::new(threads).unwrap();
            // every third value through push_if, with a rejected one before it
            let fill = |k: usize, out: &mut Stretch<u32>| {
                for v in 0..lengths[k] {
                    if v % 3 == 0 {
                        out.push_if(u32::MAX, false);
                        out.push_if(value(k, v), true);
                    } else {
                        out.push(value(k, v));
                    }
                }
            };
            let got = collect_in_order(&estimates, &pool, fill);
            // into a vector with room and old contents
            let mut reused = vec![7u32; 2000];
            collect_in_order_into(&mut reused, &estimates, &pool, fill);
            let want: Vec<u32> = lengths
                .iter()
                .enumerate()
                .flat_map(|(k, &l)| (0..l).map(move |v| value(k, v)))
                .collect();
            proptest::prop_assert_eq!(&got, &want);
            proptest::prop_assert_eq!(reused, want);
        }
    }

    #[test]
    fn every_pair_of_blocks_meets_once_and_no_block_twice_in_a_round() {
        for blocks in 0..12 {
            let rounds = tournament(blocks);
            let mut met = vec![vec![0; blocks]; blocks];
            for round in &rounds {
                let mut playing = vec![false; blocks];
                for &(a, b) in round {
                    assert!(a <= b);
                    met[a][b] += 1;
                    assert!(!playing[a] && !playing[b], "{blocks}: a block plays twice");
                    playing[a] = true;
                    playing[b] = true;
                }
            }
            for a in 0..blocks {
                for b in a..blocks {
                    assert_eq!(met[a][b], 1, "{blocks} blocks: {a} and {b}");
                }
            }
        }
    }
}
