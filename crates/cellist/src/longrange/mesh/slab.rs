//! A mesh shared by several processes (ranks), cut into slabs of planes along
//! axis 0, and its Fourier transform over them (a slab-decomposed FFT):
//!
//! 1. each rank holds the planes `part(corner, rank)` of the mesh's data corner
//!    and transforms them over the axes it holds whole (`forward_planes` of the
//!    plane transform);
//! 2. an all-to-all transpose gives each rank the columns `part(plane_len, rank)`
//!    of every plane (the spectrum along axes `1..D` cut instead of axis 0);
//! 3. each rank transforms its columns along axis 0 (`lines`);
//!
//! and the reverse for the inverse transform, whose planes come back with the
//! ghost planes the interpolation stencil reads beyond the slab. Every line is
//! transformed by the same plans as in one process, so the spectrum and the
//! fields have the same bits on any number of ranks. One rank holds both
//! phases in one buffer and transposes nothing.
//!
//! The processes talk through [`Exchange`], which the simulation layer
//! implements on MPI; [`Alone`] is the one process.

use super::fft::Planes;
use rustfft::num_complex::Complex;
use std::ops::Range;

/// The collective exchanges among the ranks that share a mesh. Every rank
/// calls each method at the same point, with counts that agree.
pub trait Exchange {
    /// This rank, in `0..ranks`.
    fn rank(&self) -> usize;

    /// The number of ranks.
    fn ranks(&self) -> usize;

    /// All-to-all: `send` holds the blocks for ranks `0, 1, ..` in order
    /// (`send_counts[r]` numbers for rank `r`), and `receive` gets the blocks
    /// of ranks `0, 1, ..` in order (`receive_counts[r]` from rank `r`).
    fn all_to_all(
        &self,
        send: &[f64],
        send_counts: &[usize],
        receive: &mut [f64],
        receive_counts: &[usize],
    );

    /// All-gather: `out` gets every rank's `mine` in rank order, `counts[r]`
    /// numbers from rank `r`.
    fn all_gather(&self, mine: &[f64], counts: &[usize], out: &mut [f64]);
}

/// The bounding box `(lo, hi)` of every rank's `positions` (collective on
/// several ranks), and their count.
pub(crate) fn extent(
    positions: &[[f64; 3]],
    exchange: &dyn Exchange,
) -> (([f64; 3], [f64; 3]), usize) {
    // a rank without particles adds nothing to the minimum and the maximum
    let (mut lo, mut hi) = if positions.is_empty() {
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3])
    } else {
        crate::geometry::bounding_box(positions)
    };
    let ranks = exchange.ranks();
    if ranks == 1 {
        return ((lo, hi), positions.len());
    }
    // lo, hi and the count of every rank
    let mine = [
        lo[0],
        lo[1],
        lo[2],
        hi[0],
        hi[1],
        hi[2],
        positions.len() as f64,
    ];
    let mut all = vec![0.0; 7 * ranks];
    exchange.all_gather(&mine, &vec![7; ranks], &mut all);
    let mut count = 0;
    for r in all.chunks_exact(7) {
        for a in 0..3 {
            lo[a] = lo[a].min(r[a]);
            hi[a] = hi[a].max(r[3 + a]);
        }
        count += r[6] as usize;
    }
    ((lo, hi), count)
}

/// The one process: rank 0 of 1.
#[derive(Clone, Copy, Debug, Default)]
pub struct Alone;

impl Exchange for Alone {
    fn rank(&self) -> usize {
        0
    }

    fn ranks(&self) -> usize {
        1
    }

    fn all_to_all(&self, send: &[f64], _: &[usize], receive: &mut [f64], _: &[usize]) {
        receive.copy_from_slice(send);
    }

    fn all_gather(&self, mine: &[f64], _: &[usize], out: &mut [f64]) {
        out.copy_from_slice(mine);
    }
}

/// The ranks among which a system that every one of them holds whole divides
/// its sums (the vortex model's PSE rates, thermo pair sums and fmm): a boxed
/// [`Exchange`], [`Alone`] by default.
pub struct Peers(Box<dyn Exchange>);

impl Peers {
    /// The ranks of `exchange`.
    pub fn new(exchange: Box<dyn Exchange>) -> Self {
        Peers(exchange)
    }

    /// The exchange among them.
    pub fn exchange(&self) -> &dyn Exchange {
        self.0.as_ref()
    }
}

impl Default for Peers {
    fn default() -> Self {
        Peers(Box::new(Alone))
    }
}

impl std::fmt::Debug for Peers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "rank {} of {}", self.0.rank(), self.0.ranks())
    }
}

/// This process's place among the ranks that share a mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rank {
    /// This rank, in `0..count`.
    pub index: usize,
    /// The number of ranks.
    pub count: usize,
}

impl Rank {
    /// The one process.
    pub const ALONE: Rank = Rank { index: 0, count: 1 };

    /// The place of `exchange`'s rank.
    pub fn of(exchange: &dyn Exchange) -> Rank {
        Rank {
            index: exchange.rank(),
            count: exchange.ranks(),
        }
    }

    /// Refuses more ranks than the `planes` of the cut axis (a rank would hold
    /// no plane) and an index out of range.
    pub(crate) fn check(&self, planes: usize) -> Result<(), String> {
        if self.count == 0 || self.index >= self.count {
            return Err(format!("rank {} of {} ranks", self.index, self.count));
        }
        if self.count > planes {
            return Err(format!(
                "{} ranks share a mesh of only {planes} planes along the cut axis (grid \
                 {planes}): a slab-decomposed mesh needs at least one plane per rank; use at \
                 most {planes} ranks or a finer grid",
                self.count
            ));
        }
        Ok(())
    }
}

impl Rank {
    /// Refuses more ranks than leave every slab of the `planes` planes at
    /// least `rows` of them (a stencil that reads `rows` planes beyond its
    /// slab from the next rank alone) and every rank a column of a plane's
    /// `columns` of half spectrum.
    pub(crate) fn check_slabs(
        &self,
        planes: usize,
        rows: usize,
        columns: usize,
    ) -> Result<(), String> {
        let most = (planes / rows.max(1)).min(columns);
        if self.count > most {
            return Err(format!(
                "{} ranks share a mesh of only {planes} planes (grid {planes}): its slabs need \
                 at least {rows} planes and one spectrum column per rank; use at most {most} \
                 ranks or a finer grid",
                self.count
            ));
        }
        Ok(())
    }
}

/// Part `r` of `len` items cut into `ranks` contiguous parts as even as can
/// be: `len r / ranks .. len (r + 1) / ranks`.
pub(crate) fn part(len: usize, r: usize, ranks: usize) -> Range<usize> {
    len * r / ranks..len * (r + 1) / ranks
}

/// The rank whose [`part`] of `len` items holds item `p`.
pub(crate) fn owner(p: usize, len: usize, ranks: usize) -> usize {
    ((p + 1) * ranks).div_ceil(len) - 1
}

/// The planes `first, first + 1, ..` (mod `M`, a power of two) that a rank holds
/// of a mesh field, `count` of them: plane `p` is at `(p - first) mod M` when that
/// is below `count`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Window {
    first: usize,
    count: usize,
    mask: usize,
}

impl Window {
    /// Every plane `0..count` of a mesh of side `m`.
    pub(crate) fn whole(count: usize, m: usize) -> Self {
        Window {
            first: 0,
            count,
            mask: m - 1,
        }
    }

    /// The planes `first..first + count` (mod `m`) of a mesh of side `m`.
    pub(crate) fn planes(first: usize, count: usize, m: usize) -> Self {
        Window {
            first: first & (m - 1),
            count,
            mask: m - 1,
        }
    }

    /// Where plane `p` is held, if it is.
    #[inline(always)]
    pub(crate) fn local(&self, p: usize) -> Option<usize> {
        let l = p.wrapping_sub(self.first) & self.mask;
        (l < self.count).then_some(l)
    }

    /// The number of planes held.
    pub(crate) fn count(&self) -> usize {
        self.count
    }
}

/// The numbers of `values`: `Complex<f64>` is laid out as `[re, im]`.
fn floats(values: &[Complex<f64>]) -> &[f64] {
    // SAFETY: num-complex's Complex is #[repr(C)] with the fields re, im, so a
    // slice of n of them is a slice of 2n f64 with the same alignment.
    unsafe { std::slice::from_raw_parts(values.as_ptr().cast::<f64>(), 2 * values.len()) }
}

/// [`floats`], mutable.
fn floats_mut(values: &mut [Complex<f64>]) -> &mut [f64] {
    // SAFETY: as in `floats`; the borrow is exclusive for the result's life.
    unsafe { std::slice::from_raw_parts_mut(values.as_mut_ptr().cast::<f64>(), 2 * values.len()) }
}

/// [`Slab::window`] of `rank` (of several) on a mesh of side `m`.
fn window_of(corner: usize, m: usize, rank: Rank, (below, above): (usize, usize)) -> Window {
    let owned = part(corner, rank.index, rank.count);
    Window::planes(owned.start + m - below, owned.len() + below + above, m)
}

/// A transform ([`Planes`]) of a mesh cut into slabs over the ranks.
pub(crate) struct Slab<F: Planes> {
    fft: F,
    rank: Rank,
    /// The plane phase's planes (several ranks only).
    planes: Vec<Complex<f64>>,
    send: Vec<Complex<f64>>,
    receive: Vec<Complex<f64>>,
}

impl<F: Planes> Slab<F> {
    /// The transform `fft` on `rank`'s slab.
    pub(crate) fn new(fft: F, rank: Rank) -> Self {
        Slab {
            fft,
            rank,
            planes: Vec::new(),
            send: Vec::new(),
            receive: Vec::new(),
        }
    }

    /// The mesh side `M`.
    pub(crate) fn size(&self) -> usize {
        self.fft.size()
    }

    /// The place.
    pub(crate) fn rank(&self) -> Rank {
        self.rank
    }

    /// Complex numbers in one plane's half spectrum.
    pub(crate) fn plane_len(&self) -> usize {
        self.fft.plane_len()
    }

    /// This rank's columns of a plane's half spectrum (the second phase's).
    pub(crate) fn columns(&self) -> Range<usize> {
        part(self.plane_len(), self.rank.index, self.rank.count)
    }

    /// Complex numbers of the second phase's buffer: `M` rows of
    /// [`Slab::columns`].
    pub(crate) fn lines_len(&self) -> usize {
        self.size() * self.columns().len()
    }

    /// This rank's planes of a data corner of `corner` planes.
    pub(crate) fn owned(&self, corner: usize) -> Range<usize> {
        part(corner, self.rank.index, self.rank.count)
    }

    /// The planes of [`Slab::owned`] as a window.
    pub(crate) fn owned_window(&self, corner: usize) -> Window {
        self.window(corner, 0, 0)
    }

    /// The planes [`Slab::inverse`] writes: this rank's planes with `below` and
    /// `above` more on either side (mod `M`; the whole corner on one rank).
    pub(crate) fn window(&self, corner: usize, below: usize, above: usize) -> Window {
        let m = self.size();
        if self.rank.count == 1 {
            return Window::whole(corner, m);
        }
        window_of(corner, m, self.rank, (below, above))
    }

    /// `lines` (the [`Slab::lines_len`] buffer) = this rank's columns of the
    /// spectrum of the mesh that `row` gives on the `corner` cube
    /// ([`Planes::forward_planes`]): `row` is called for this rank's planes only.
    pub(crate) fn forward(
        &mut self,
        corner: usize,
        lines: &mut [Complex<f64>],
        row: impl Fn(usize, usize, &mut [f64]) + Sync,
        exchange: &dyn Exchange,
        threads: &crate::Threads,
    ) {
        debug_assert_eq!(Rank::of(exchange), self.rank);
        let width = self.columns().len();
        if self.rank.count == 1 {
            threads.install(|| self.fft.forward(corner, lines, &row));
            return;
        }
        let owned = self.owned(corner);
        let len = self.plane_len();
        self.planes.resize(owned.len() * len, Complex::default());
        threads.install(|| {
            self.fft
                .forward_planes(corner, owned.start, &mut self.planes, &row)
        });
        // to rank s: its columns of each of my planes
        let ranks = self.rank.count;
        let send_counts: Vec<usize> = (0..ranks)
            .map(|s| 2 * owned.len() * part(len, s, ranks).len())
            .collect();
        let receive_counts: Vec<usize> = (0..ranks)
            .map(|r| 2 * part(corner, r, ranks).len() * width)
            .collect();
        self.send.clear();
        for s in 0..ranks {
            let cols = part(len, s, ranks);
            for plane in self.planes.chunks(len) {
                self.send.extend_from_slice(&plane[cols.clone()]);
            }
        }
        // from rank r: my columns of its planes, which are rows of `lines`
        let from = corner.min(self.size()) * width;
        lines[from..].fill(Complex::default());
        exchange.all_to_all(
            floats(&self.send),
            &send_counts,
            floats_mut(&mut lines[..from]),
            &receive_counts,
        );
        threads.install(|| self.fft.lines(lines, width, false));
    }

    /// `out` = the planes of `window(corner, below, above)` (each the
    /// `[0, corner)^(D-1)` corner, `corner^(D-1)` numbers) of the inverse
    /// transform of this rank's columns `lines`, which are used as scratch.
    pub(crate) fn inverse(
        &mut self,
        corner: usize,
        lines: &mut [Complex<f64>],
        out: &mut [f64],
        ghosts: (usize, usize),
        exchange: &dyn Exchange,
        threads: &crate::Threads,
    ) {
        debug_assert_eq!(Rank::of(exchange), self.rank);
        if self.rank.count == 1 {
            threads.install(|| self.fft.inverse(corner, lines, out));
            return;
        }
        let width = self.columns().len();
        threads.install(|| self.fft.lines(lines, width, true));
        let (m, len, ranks) = (self.size(), self.plane_len(), self.rank.count);
        let windows: Vec<Window> = (0..ranks)
            .map(|r| {
                window_of(
                    corner,
                    m,
                    Rank {
                        index: r,
                        count: ranks,
                    },
                    ghosts,
                )
            })
            .collect();
        // to rank r: the rows of its window, my columns
        let send_counts: Vec<usize> = windows.iter().map(|w| 2 * w.count * width).collect();
        let mine = windows[self.rank.index];
        let receive_counts: Vec<usize> = (0..ranks)
            .map(|s| 2 * mine.count * part(len, s, ranks).len())
            .collect();
        self.send.clear();
        for w in &windows {
            for k in 0..w.count {
                let q0 = (w.first + k) & (m - 1);
                self.send.extend_from_slice(&lines[q0 * width..][..width]);
            }
        }
        self.receive
            .resize(receive_counts.iter().sum::<usize>() / 2, Complex::default());
        exchange.all_to_all(
            floats(&self.send),
            &send_counts,
            floats_mut(&mut self.receive),
            &receive_counts,
        );
        self.planes.resize(mine.count * len, Complex::default());
        unpack_columns(&self.receive, &mut self.planes, len, ranks);
        threads.install(|| self.fft.inverse_planes(corner, &mut self.planes, out));
    }

    /// `out` (`k`-th chunk of [`Slab::plane_len`]: row `wanting(columns)[k]`)
    /// = whole rows (planes' half spectra) of a real array `a(q0, c)` of which
    /// every rank holds its columns of every row (`mine`: `M` rows of
    /// [`Slab::columns`]), `wanting(cols)` being the rows that the rank of
    /// columns `cols` asks for: one all-to-all, in which every value travels
    /// as it is (the same bits as reading a whole array in one process).
    pub(crate) fn whole_rows(
        &self,
        mine: &[f64],
        wanting: impl Fn(Range<usize>) -> Vec<usize>,
        out: &mut [f64],
        exchange: &dyn Exchange,
    ) {
        debug_assert_eq!(Rank::of(exchange), self.rank);
        let (len, ranks) = (self.plane_len(), self.rank.count);
        let width = self.columns().len();
        debug_assert_eq!(mine.len(), self.size() * width);
        let asked: Vec<Vec<usize>> = (0..ranks).map(|r| wanting(part(len, r, ranks))).collect();
        // to rank r: my columns of each row it asks for
        let send_counts: Vec<usize> = asked.iter().map(|rows| rows.len() * width).collect();
        let send: Vec<f64> = asked
            .iter()
            .flatten()
            .flat_map(|&q0| &mine[q0 * width..][..width])
            .copied()
            .collect();
        let rows = asked[self.rank.index].len();
        debug_assert_eq!(out.len(), rows * len);
        // from rank s: its columns of each of my rows
        let receive_counts: Vec<usize> = (0..ranks)
            .map(|s| rows * part(len, s, ranks).len())
            .collect();
        let mut receive = vec![0.0; rows * len];
        exchange.all_to_all(&send, &send_counts, &mut receive, &receive_counts);
        unpack_columns(&receive, out, len, ranks);
    }

    /// The sum over the ranks of each rank's `partial`, in rank order (the
    /// same bits on every rank).
    pub(crate) fn sum<const W: usize>(
        &self,
        partial: [f64; W],
        exchange: &dyn Exchange,
    ) -> [f64; W] {
        if self.rank.count == 1 {
            return partial;
        }
        let ranks = self.rank.count;
        let mut all = vec![0.0; W * ranks];
        exchange.all_gather(&partial, &vec![W; ranks], &mut all);
        let mut total = [0.0; W];
        for chunk in all.chunks_exact(W) {
            for (t, v) in total.iter_mut().zip(chunk) {
                *t += v;
            }
        }
        total
    }
}

/// `rows` (chunks of a plane's half spectrum of `len` numbers) = the blocks of
/// `received` from the ranks `0, 1, ..` in order, rank `s`'s block holding its
/// columns `part(len, s, ranks)` of each row in turn.
fn unpack_columns<T: Copy>(received: &[T], rows: &mut [T], len: usize, ranks: usize) {
    let mut from = received;
    for s in 0..ranks {
        let cols = part(len, s, ranks);
        for row in rows.chunks_mut(len) {
            let (block, rest) = from.split_at(cols.len());
            row[cols.clone()].copy_from_slice(block);
            from = rest;
        }
    }
}

#[cfg(test)]
pub(crate) mod testkit {
    //! An [`Exchange`] among threads of one process, for tests of the slab
    //! decomposition without MPI.

    use super::Exchange;
    use std::sync::{Barrier, Mutex};

    /// The mailboxes of `ranks` threads.
    pub(crate) struct Hub {
        ranks: usize,
        barrier: Barrier,
        /// `boxes[from][to]`.
        boxes: Mutex<Vec<Vec<Vec<f64>>>>,
    }

    impl Hub {
        pub(crate) fn new(ranks: usize) -> Self {
            Hub {
                ranks,
                barrier: Barrier::new(ranks),
                boxes: Mutex::new(vec![vec![Vec::new(); ranks]; ranks]),
            }
        }

        /// Runs `body(exchange)` on one thread per rank; the results in rank order.
        pub(crate) fn run<T: Send>(ranks: usize, body: impl Fn(&Threaded) -> T + Sync) -> Vec<T> {
            let hub = Hub::new(ranks);
            std::thread::scope(|scope| {
                let handles: Vec<_> = (0..ranks)
                    .map(|rank| {
                        let (hub, body) = (&hub, &body);
                        scope.spawn(move || body(&Threaded { hub, rank }))
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            })
        }
    }

    /// One rank's end of a [`Hub`].
    pub(crate) struct Threaded<'a> {
        hub: &'a Hub,
        rank: usize,
    }

    impl Exchange for Threaded<'_> {
        fn rank(&self) -> usize {
            self.rank
        }

        fn ranks(&self) -> usize {
            self.hub.ranks
        }

        fn all_to_all(
            &self,
            send: &[f64],
            send_counts: &[usize],
            receive: &mut [f64],
            receive_counts: &[usize],
        ) {
            let mut at = 0;
            {
                let mut boxes = self.hub.boxes.lock().unwrap();
                for (to, &count) in send_counts.iter().enumerate() {
                    boxes[self.rank][to] = send[at..at + count].to_vec();
                    at += count;
                }
            }
            self.hub.barrier.wait();
            {
                let boxes = self.hub.boxes.lock().unwrap();
                let mut at = 0;
                for (from, &count) in receive_counts.iter().enumerate() {
                    let block = &boxes[from][self.rank];
                    assert_eq!(block.len(), count, "from {from} to {}", self.rank);
                    receive[at..at + count].copy_from_slice(block);
                    at += count;
                }
            }
            self.hub.barrier.wait();
        }

        fn all_gather(&self, mine: &[f64], counts: &[usize], out: &mut [f64]) {
            let sends = vec![mine.len(); self.hub.ranks];
            let all: Vec<f64> = std::iter::repeat_n(mine, self.hub.ranks)
                .flatten()
                .copied()
                .collect();
            self.all_to_all(&all, &sends, out, counts);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testkit::Hub;
    use super::*;
    use crate::longrange::mesh::fft::{Fft2, Fft3};
    use crate::random::Rng;
    use crate::Threads;

    /// A mesh of random values on the `corner` cube of an `M^3` mesh.
    fn values(corner: usize, seed: u64) -> Vec<f64> {
        let mut rng = Rng::new(seed);
        (0..corner * corner * corner)
            .map(|_| rng.uniform() - 0.5)
            .collect()
    }

    /// The slab transform of `mesh` on `ranks` ranks, forward (each rank's
    /// columns of the spectrum, concatenated over the ranks as columns of every
    /// row) and back (each rank's window of planes with one ghost below and two
    /// above).
    fn slab3(
        m: usize,
        corner: usize,
        mesh: &[f64],
        ranks: usize,
    ) -> Vec<(Vec<Complex<f64>>, Vec<f64>)> {
        Hub::run(ranks, |exchange| {
            let rank = Rank::of(exchange);
            let mut slab = Slab::new(Fft3::new(m), rank);
            let mut lines = vec![Complex::default(); slab.lines_len()];
            let threads = Threads::single();
            slab.forward(
                corner,
                &mut lines,
                |i, j, row| row.copy_from_slice(&mesh[(i * corner + j) * corner..][..corner]),
                exchange,
                &threads,
            );
            let spectrum = lines.clone();
            let window = slab.window(corner, 1, 2);
            let mut out = vec![0.0; window.count() * corner * corner];
            slab.inverse(corner, &mut lines, &mut out, (1, 2), exchange, &threads);
            (spectrum, out)
        })
    }

    #[test]
    fn the_slab_transform_has_the_bits_of_the_whole_one() {
        // periodic (the whole mesh) and zero-padded (a corner of half the side)
        for (m, corner) in [(16, 16), (16, 8)] {
            let mesh = values(corner, 3);
            let mut fft = Fft3::new(m);
            let len = fft.plane_len();
            let mut want = vec![Complex::default(); m * len];
            fft.forward(corner, &mut want, |i, j, row| {
                row.copy_from_slice(&mesh[(i * corner + j) * corner..][..corner])
            });
            let spectrum = want.clone();
            let mut back = vec![0.0; corner * corner * corner];
            fft.inverse(corner, &mut want, &mut back);
            // the unnormalised inverse is M^3 times the mesh
            let scale = (m * m * m) as f64;
            for (b, v) in back.iter().zip(&mesh) {
                assert!((b / scale - v).abs() < 1e-13, "{b} {v}");
            }
            for ranks in [1, 2, 3, 4] {
                let got = slab3(m, corner, &mesh, ranks);
                for (r, (lines, planes)) in got.iter().enumerate() {
                    let cols = part(len, r, ranks);
                    for q0 in 0..m {
                        let row = &lines[q0 * cols.len()..][..cols.len()];
                        assert_eq!(
                            row,
                            &spectrum[q0 * len..][cols.clone()],
                            "rank {r} of {ranks}"
                        );
                    }
                    let plane = corner * corner;
                    let window = if ranks == 1 {
                        (0..corner).collect::<Vec<_>>()
                    } else {
                        let owned = part(corner, r, ranks);
                        (0..owned.len() + 3)
                            .map(|k| (owned.start + m + k - 1) % m)
                            .collect()
                    };
                    for (k, &p) in window.iter().enumerate() {
                        let got = &planes[k * plane..][..plane];
                        if p < corner {
                            assert_eq!(got, &back[p * plane..][..plane], "rank {r} plane {p}");
                        } else {
                            // outside the corner: the padding, zero up to rounding
                            assert!(got.iter().all(|v| v.abs() < 1e-12 * scale), "plane {p}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_slab_transform_of_rows_has_the_bits_of_the_whole_one() {
        let (m, corner) = (32, 16);
        let mut rng = Rng::new(5);
        let mesh: Vec<f64> = (0..corner * corner).map(|_| rng.uniform()).collect();
        let mut fft = Fft2::new(m);
        let len = fft.plane_len();
        let mut want = vec![Complex::default(); m * len];
        fft.forward(corner, &mut want, |i, _, row| {
            row.copy_from_slice(&mesh[i * corner..][..corner])
        });
        for ranks in [2, 3] {
            let got = Hub::run(ranks, |exchange| {
                let mut slab = Slab::new(Fft2::new(m), Rank::of(exchange));
                let mut lines = vec![Complex::default(); slab.lines_len()];
                slab.forward(
                    corner,
                    &mut lines,
                    |i, _, row| row.copy_from_slice(&mesh[i * corner..][..corner]),
                    exchange,
                    &Threads::single(),
                );
                lines
            });
            for (r, lines) in got.iter().enumerate() {
                let cols = part(len, r, ranks);
                for q0 in 0..m {
                    assert_eq!(
                        &lines[q0 * cols.len()..][..cols.len()],
                        &want[q0 * len..][cols.clone()]
                    );
                }
            }
        }
    }

    #[test]
    fn whole_rows_are_the_rows_of_the_whole_array() {
        // a 16 x 9 array (a 2-d mesh of side 16), each rank asking for rows set
        // by its columns, one of them twice
        let (m, len) = (16, 9);
        let mut rng = Rng::new(11);
        let whole: Vec<f64> = (0..m * len).map(|_| rng.uniform()).collect();
        let asks = |cols: Range<usize>| vec![(3 * cols.start + 5) % m, cols.end % m, 0, 0];
        for ranks in [1, 2, 3, 4] {
            let got = Hub::run(ranks, |exchange| {
                let slab = Slab::new(Fft2::new(m), Rank::of(exchange));
                let cols = slab.columns();
                let mine: Vec<f64> = (0..m)
                    .flat_map(|q0| whole[q0 * len..][cols.clone()].to_vec())
                    .collect();
                let mut out = vec![0.0; 4 * len];
                slab.whole_rows(&mine, asks, &mut out, exchange);
                (cols, out)
            });
            for (r, (cols, out)) in got.into_iter().enumerate() {
                for (row, q0) in out.chunks(len).zip(asks(cols)) {
                    assert_eq!(row, &whole[q0 * len..][..len], "rank {r} of {ranks}");
                }
            }
        }
    }

    #[test]
    fn every_item_has_the_owner_whose_part_holds_it() {
        for (len, ranks) in [(8, 1), (8, 3), (16, 4), (9, 9), (100, 7), (2, 4), (3, 8)] {
            for r in 0..ranks {
                for p in part(len, r, ranks) {
                    assert_eq!(owner(p, len, ranks), r, "{p} of {len} on {ranks}");
                }
            }
        }
    }

    #[test]
    fn more_ranks_than_planes_are_refused() {
        assert!(Rank { index: 0, count: 8 }.check(8).is_ok());
        let e = Rank { index: 0, count: 9 }.check(8).unwrap_err();
        assert!(e.contains("9 ranks") && e.contains("8 planes"), "{e}");
    }
}
