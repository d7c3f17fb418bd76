//! Real discrete Fourier transforms of square meshes of side `M`: the 3-d one of
//! an `M^3` mesh ([`Fft3`]), stored as the half spectrum `F(q0, q1, q2)` for
//! `q2 <= M/2` at `(q0 M + q1) H + q2`, `H = M/2 + 1`,
//!
//! `F(q) = sum_x f(x) exp(-2 pi i q.x / M)` (forward, [`Fft3::forward`]) and
//! `f(x) = sum_q F(q) exp(+2 pi i q.x / M)` (inverse, unnormalised, [`Fft3::inverse`]),
//!
//! and the 2-d one of an `M^2` mesh ([`Fft2`]), the same with `F(q0, q1)` for
//! `q1 <= M/2` at `q0 H + q1`.
//!
//! Both are pruned to a corner `[0, m)^d` of the mesh: the forward transform takes
//! a mesh that is zero outside it, the inverse writes only that corner (`m = M`
//! for periodic meshes, `m = M/2` for zero-padded isolated ones). Both are built
//! from the same 1-d plans ([`Plans`]) and line passes (a row's real transform,
//! [`strided`] lines of the complex one). Each 1-d line is transformed on its own,
//! so lines run in parallel and the bits do not depend on the thread count.

use crate::threads::DisjointSlice;
use rayon::prelude::*;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::ops::Range;
use std::sync::Arc;

/// Lines gathered per strided pass: 4 complex numbers fill a 64-byte cache line.
const BATCH: usize = 4;

/// One task's private buffers.
struct Slot {
    real: Vec<f64>,
    lines: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

/// The 1-d plans of lines of length `M` (even).
struct Plans {
    m: usize,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    scratch: usize,
}

impl Plans {
    fn new(m: usize) -> Self {
        let mut real = RealFftPlanner::<f64>::new();
        let mut complex = FftPlanner::<f64>::new();
        let (r2c, c2r) = (real.plan_fft_forward(m), real.plan_fft_inverse(m));
        let (forward, inverse) = (complex.plan_fft_forward(m), complex.plan_fft_inverse(m));
        let scratch = [
            r2c.get_scratch_len(),
            c2r.get_scratch_len(),
            forward.get_inplace_scratch_len(),
            inverse.get_inplace_scratch_len(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        Plans {
            m,
            r2c,
            c2r,
            forward,
            inverse,
            scratch,
        }
    }

    /// Fresh buffers for one task.
    fn slot(&self) -> Slot {
        Slot {
            real: vec![0.0; self.m],
            lines: vec![Complex::default(); BATCH * self.m],
            scratch: vec![Complex::default(); self.scratch],
        }
    }

    /// `out` (`M/2 + 1`) = the r2c transform of the row whose first `corner`
    /// points `fill` writes and whose others are zero.
    #[inline]
    fn row_forward(
        &self,
        corner: usize,
        slot: &mut Slot,
        out: &mut [Complex<f64>],
        fill: impl FnOnce(&mut [f64]),
    ) {
        slot.real[corner..].fill(0.0);
        fill(&mut slot.real[..corner]);
        self.r2c
            .process_with_scratch(&mut slot.real, out, &mut slot.scratch)
            .expect("r2c buffers have the planned lengths");
    }

    /// The first `row.len()` points of the c2r transform of `line` (`M/2 + 1`,
    /// used as scratch).
    #[inline]
    fn row_inverse(&self, slot: &mut Slot, line: &mut [Complex<f64>], row: &mut [f64]) {
        // The imaginary parts of q = 0 and M/2 vanish for a real f; round-off is
        // dropped so that the real transform accepts them.
        let h = line.len();
        line[0].im = 0.0;
        line[h - 1].im = 0.0;
        self.c2r
            .process_with_scratch(line, &mut slot.real, &mut slot.scratch)
            .expect("c2r buffers have the planned lengths");
        row.copy_from_slice(&slot.real[..row.len()]);
    }
}

/// A real transform cut into planes along axis 0: a `D`-dimensional mesh of
/// side `M` is `M` planes (3-d: `M^2`, 2-d: one row of `M`), each transformed
/// on its own over the axes it holds whole (the plane phase, [`Planes::forward_planes`],
/// [`Planes::inverse_planes`]), into `plane_len` complex numbers; then the `c2c`
/// transform along axis 0 of each of these columns ([`Planes::lines`]). A
/// process holding every plane does both on one buffer; a slab-decomposed one
/// (module `slab`) holds some planes in the first phase, some columns of every
/// plane in the second, with a transpose between.
pub(crate) trait Planes: Send {
    /// The mesh side `M`.
    fn size(&self) -> usize;

    /// Complex numbers in one plane's half spectrum.
    fn plane_len(&self) -> usize;

    /// `spec` (`k`-th chunk of [`Planes::plane_len`]: plane `first + k`) = the
    /// plane phase of the mesh that is `row(i, j)` on the first `corner` points
    /// of row `j < corner` of plane `i < corner` (2-d: the plane is row `j = 0`)
    /// and zero elsewhere; `row` fills a slice of length `corner`.
    fn forward_planes(
        &mut self,
        corner: usize,
        first: usize,
        spec: &mut [Complex<f64>],
        row: impl Fn(usize, usize, &mut [f64]) + Sync,
    );

    /// The inverse plane phase of the planes in `spec` (used as scratch): their
    /// corner `[0, corner)^(D-1)` written to `out`, `corner^(D-1)` numbers per
    /// plane.
    fn inverse_planes(&mut self, corner: usize, spec: &mut [Complex<f64>], out: &mut [f64]);

    /// The `c2c` transform along axis 0 of the `width` columns of `spec`
    /// (`M` rows of `width`, the lines at stride `width`), forward or inverse.
    fn lines(&mut self, spec: &mut [Complex<f64>], width: usize, inverse: bool);

    /// `spec = F` of the mesh that `row` gives (as in [`Planes::forward_planes`]),
    /// every plane in this process.
    fn forward(
        &mut self,
        corner: usize,
        spec: &mut [Complex<f64>],
        row: impl Fn(usize, usize, &mut [f64]) + Sync,
    ) {
        let width = self.plane_len();
        self.forward_planes(corner, 0, spec, row);
        self.lines(spec, width, false);
    }

    /// Writes `f(x)` for `x in [0, corner)^D` to `out` (row-major) from
    /// `spec = F`, every plane in this process; `spec` is used as scratch.
    fn inverse(&mut self, corner: usize, spec: &mut [Complex<f64>], out: &mut [f64]) {
        let width = self.plane_len();
        self.lines(spec, width, true);
        self.inverse_planes(corner, &mut spec[..corner * width], out);
    }
}

/// Plans and per-task buffers for transforms of one `M^3` mesh size.
pub(crate) struct Fft3 {
    plans: Plans,
    slots: Vec<Slot>,
}

impl Fft3 {
    /// Plans for an `M^3` mesh (`M` even).
    pub(crate) fn new(m: usize) -> Self {
        let plans = Plans::new(m);
        let slots = (0..m).map(|_| plans.slot()).collect();
        Fft3 { plans, slots }
    }
}

impl Planes for Fft3 {
    fn size(&self) -> usize {
        self.plans.m
    }

    /// `M (M/2 + 1)`: the plane's rows' half spectra, `F(q1, q2)` at `q1 H + q2`.
    fn plane_len(&self) -> usize {
        self.plans.m * (self.plans.m / 2 + 1)
    }

    /// One task per plane: the rows' `r2c` transforms, then the columns' `c2c`.
    fn forward_planes(
        &mut self,
        corner: usize,
        first: usize,
        spec: &mut [Complex<f64>],
        row: impl Fn(usize, usize, &mut [f64]) + Sync,
    ) {
        let plans = &self.plans;
        let (m, h) = (plans.m, plans.m / 2 + 1);
        spec.par_chunks_mut(m * h)
            .zip(self.slots.par_iter_mut())
            .enumerate()
            .for_each(|(k, (plane, slot))| {
                let i = first + k;
                if i >= corner {
                    plane.fill(Complex::default());
                    return;
                }
                for (j, out) in plane.chunks_mut(h).enumerate() {
                    if j < corner {
                        plans.row_forward(corner, slot, out, |r| row(i, j, r));
                    } else {
                        out.fill(Complex::default());
                    }
                }
                columns(plane, h, plans.forward.as_ref(), slot);
            });
    }

    fn inverse_planes(&mut self, corner: usize, spec: &mut [Complex<f64>], out: &mut [f64]) {
        let plans = &self.plans;
        let (m, h) = (plans.m, plans.m / 2 + 1);
        spec.par_chunks_mut(m * h)
            .zip(out.par_chunks_mut(corner * corner))
            .zip(self.slots.par_iter_mut())
            .for_each(|((plane, rows), slot)| {
                columns(plane, h, plans.inverse.as_ref(), slot);
                for (line, row) in plane.chunks_mut(h).zip(rows.chunks_mut(corner)) {
                    plans.row_inverse(slot, line, row);
                }
            });
    }

    fn lines(&mut self, spec: &mut [Complex<f64>], width: usize, inverse: bool) {
        lines(&self.plans, &mut self.slots, spec, width, inverse);
    }
}

/// Tasks of a 2-d transform: a fixed number (set by `M` alone, not by the thread
/// count), each with its own buffers.
fn tasks2(m: usize) -> usize {
    (m / 32).clamp(1, 64)
}

/// Plans and per-task buffers for transforms of one `M^2` mesh size.
pub(crate) struct Fft2 {
    plans: Plans,
    slots: Vec<Slot>,
}

impl Fft2 {
    /// Plans for an `M^2` mesh (`M` even).
    pub(crate) fn new(m: usize) -> Self {
        let plans = Plans::new(m);
        let slots = (0..tasks2(m)).map(|_| plans.slot()).collect();
        Fft2 { plans, slots }
    }
}

impl Planes for Fft2 {
    fn size(&self) -> usize {
        self.plans.m
    }

    /// `M/2 + 1`: a row's half spectrum `F(q1)`.
    fn plane_len(&self) -> usize {
        self.plans.m / 2 + 1
    }

    /// Each task takes a fixed band of rows (set by `M` alone).
    fn forward_planes(
        &mut self,
        corner: usize,
        first: usize,
        spec: &mut [Complex<f64>],
        row: impl Fn(usize, usize, &mut [f64]) + Sync,
    ) {
        let plans = &self.plans;
        let (m, h) = (plans.m, plans.m / 2 + 1);
        let band = m.div_ceil(self.slots.len());
        spec.par_chunks_mut(band * h)
            .zip(self.slots.par_iter_mut())
            .enumerate()
            .for_each(|(b, (rows, slot))| {
                for (k, out) in rows.chunks_mut(h).enumerate() {
                    let i = first + b * band + k;
                    if i < corner {
                        plans.row_forward(corner, slot, out, |r| row(i, 0, r));
                    } else {
                        out.fill(Complex::default());
                    }
                }
            });
    }

    fn inverse_planes(&mut self, corner: usize, spec: &mut [Complex<f64>], out: &mut [f64]) {
        let plans = &self.plans;
        let h = plans.m / 2 + 1;
        let band = plans.m.div_ceil(self.slots.len());
        spec.par_chunks_mut(band * h)
            .zip(out.par_chunks_mut(band * corner))
            .zip(self.slots.par_iter_mut())
            .for_each(|((lines, rows), slot)| {
                for (line, row) in lines.chunks_mut(h).zip(rows.chunks_mut(corner)) {
                    plans.row_inverse(slot, line, row);
                }
            });
    }

    fn lines(&mut self, spec: &mut [Complex<f64>], width: usize, inverse: bool) {
        lines(&self.plans, &mut self.slots, spec, width, inverse);
    }
}

/// The `c2c` transform along axis 0 of the `width` columns of `spec` (`M` rows
/// of `width`), each task (one per slot) taking a fixed range of whole batches
/// of columns. Every line is transformed on its own, so the bits depend
/// neither on the tasks nor on which columns a process holds.
fn lines(
    plans: &Plans,
    slots: &mut [Slot],
    spec: &mut [Complex<f64>],
    width: usize,
    inverse: bool,
) {
    debug_assert_eq!(spec.len(), plans.m * width);
    let fft = if inverse {
        &plans.inverse
    } else {
        &plans.forward
    };
    let per_task = width.div_ceil(slots.len()).next_multiple_of(BATCH);
    let shared = DisjointSlice::new(spec);
    slots.par_iter_mut().enumerate().for_each(|(t, slot)| {
        let cols = (t * per_task).min(width)..((t + 1) * per_task).min(width);
        // SAFETY: the tasks' column ranges are disjoint.
        unsafe { strided(&shared, 0, width, cols, fft.as_ref(), slot) };
    });
}

/// Transforms the `H` columns of one plane (`data[c + q1 H]`, `q1 < M`).
fn columns(data: &mut [Complex<f64>], h: usize, fft: &dyn Fft<f64>, slot: &mut Slot) {
    let shared = DisjointSlice::new(data);
    // SAFETY: the plane is borrowed mutably for the call.
    unsafe { strided(&shared, 0, h, 0..h, fft, slot) };
}

/// Transforms with `fft` (length `M`) the lines `data[base + c + k stride]`,
/// `k < M`, of the columns `c in cols`, gathered [`BATCH`] at a time.
///
/// # Safety
/// No other task may access these elements during the call.
unsafe fn strided(
    data: &DisjointSlice<Complex<f64>>,
    base: usize,
    stride: usize,
    cols: Range<usize>,
    fft: &dyn Fft<f64>,
    slot: &mut Slot,
) {
    let m = fft.len();
    for first in cols.clone().step_by(BATCH) {
        let batch = BATCH.min(cols.end - first);
        let lines = &mut slot.lines[..batch * m];
        for k in 0..m {
            for b in 0..batch {
                // SAFETY: the caller's promise.
                lines[b * m + k] = unsafe { *data.get(base + first + b + k * stride) };
            }
        }
        fft.process_with_scratch(lines, &mut slot.scratch);
        for k in 0..m {
            for b in 0..batch {
                // SAFETY: as above.
                unsafe { *data.get(base + first + b + k * stride) = lines[b * m + k] };
            }
        }
    }
}
