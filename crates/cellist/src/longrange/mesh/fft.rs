//! The 3-d real discrete Fourier transform of an `M^3` mesh, stored as the
//! half spectrum `F(q0, q1, q2)` for `q2 <= M/2` at `(q0 M + q1) H + q2`,
//! `H = M/2 + 1`:
//!
//! `F(q) = sum_x f(x) exp(-2 pi i q.x / M)` (forward, [`Fft3::forward`]) and
//! `f(x) = sum_q F(q) exp(+2 pi i q.x / M)` (inverse, unnormalised, [`Fft3::inverse`]).
//!
//! Both are pruned to a corner `[0, m)^3` of the mesh: the forward transform takes
//! a mesh that is zero outside it, the inverse writes only that corner (`m = M`
//! for periodic meshes, `m = M/2` for zero-padded isolated ones). Each 1-d line is
//! transformed on its own, so lines run in parallel and the bits do not depend on
//! the thread count.

use crate::threads::DisjointSlice;
use rayon::prelude::*;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Lines gathered per strided pass: 4 complex numbers fill a 64-byte cache line.
const BATCH: usize = 4;

/// One task's private buffers.
struct Slot {
    real: Vec<f64>,
    lines: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
}

/// Plans and per-task buffers for transforms of one mesh size `M`.
pub(crate) struct Fft3 {
    m: usize,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    slots: Vec<Slot>,
}

impl Fft3 {
    /// Plans for an `M^3` mesh (`M` even).
    pub(crate) fn new(m: usize) -> Self {
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
        let slots = (0..m)
            .map(|_| Slot {
                real: vec![0.0; m],
                lines: vec![Complex::default(); BATCH * m],
                scratch: vec![Complex::default(); scratch],
            })
            .collect();
        Fft3 {
            m,
            r2c,
            c2r,
            forward,
            inverse,
            slots,
        }
    }

    /// The mesh side `M`.
    pub(crate) fn size(&self) -> usize {
        self.m
    }

    /// Complex numbers in the half spectrum, `M^2 (M/2 + 1)`.
    pub(crate) fn spectrum_len(&self) -> usize {
        self.m * self.m * (self.m / 2 + 1)
    }

    /// `spec = F` of the mesh that is `row(i, j)` on the first `m` points of row
    /// `(i, j)` for `i, j < m` and zero elsewhere; `row` fills a slice of length
    /// `m`.
    pub(crate) fn forward(
        &mut self,
        corner: usize,
        spec: &mut [Complex<f64>],
        row: impl Fn(usize, usize, &mut [f64]) + Sync,
    ) {
        let (m, h) = (self.m, self.m / 2 + 1);
        let (r2c, fft) = (&self.r2c, &self.forward);
        spec.par_chunks_mut(m * h)
            .zip(self.slots.par_iter_mut())
            .enumerate()
            .for_each(|(i, (plane, slot))| {
                if i >= corner {
                    plane.fill(Complex::default());
                    return;
                }
                for (j, out) in plane.chunks_mut(h).enumerate() {
                    if j < corner {
                        slot.real[corner..].fill(0.0);
                        row(i, j, &mut slot.real[..corner]);
                        r2c.process_with_scratch(&mut slot.real, out, &mut slot.scratch)
                            .expect("r2c buffers have the planned lengths");
                    } else {
                        out.fill(Complex::default());
                    }
                }
                columns(plane, h, m, fft.as_ref(), slot);
            });
        self.axis0(spec, false);
    }

    /// Writes `f(x)` for `x in [0, m)^3` to `out` (`m^3`, row-major) from
    /// `spec = F`, which is used as scratch.
    pub(crate) fn inverse(&mut self, corner: usize, spec: &mut [Complex<f64>], out: &mut [f64]) {
        let (m, h) = (self.m, self.m / 2 + 1);
        self.axis0(spec, true);
        let (c2r, fft) = (&self.c2r, &self.inverse);
        spec.par_chunks_mut(m * h)
            .zip(out.par_chunks_mut(corner * corner))
            .zip(self.slots.par_iter_mut())
            .for_each(|((plane, rows), slot)| {
                columns(plane, h, m, fft.as_ref(), slot);
                for (line, row) in plane.chunks_mut(h).zip(rows.chunks_mut(corner)) {
                    // The imaginary parts of q2 = 0 and M/2 vanish for a real f;
                    // round-off is dropped so that the real transform accepts them.
                    line[0].im = 0.0;
                    line[h - 1].im = 0.0;
                    c2r.process_with_scratch(line, &mut slot.real, &mut slot.scratch)
                        .expect("c2r buffers have the planned lengths");
                    row.copy_from_slice(&slot.real[..corner]);
                }
            });
    }

    /// The c2c transform along axis 0 (stride `M H`), one task per `q1`.
    fn axis0(&mut self, spec: &mut [Complex<f64>], inverse: bool) {
        let (m, h) = (self.m, self.m / 2 + 1);
        let fft = if inverse {
            &self.inverse
        } else {
            &self.forward
        };
        let shared = DisjointSlice::new(spec);
        self.slots
            .par_iter_mut()
            .enumerate()
            .for_each(|(q1, slot)| {
                // Task q1 owns the elements (q0 M + q1) H + q2.
                let at = |q0: usize, q2: usize| (q0 * m + q1) * h + q2;
                for first in (0..h).step_by(BATCH) {
                    let batch = BATCH.min(h - first);
                    let lines = &mut slot.lines[..batch * m];
                    for q0 in 0..m {
                        for b in 0..batch {
                            // SAFETY: only task q1 reaches this element.
                            lines[b * m + q0] = unsafe { *shared.get(at(q0, first + b)) };
                        }
                    }
                    fft.process_with_scratch(lines, &mut slot.scratch);
                    for q0 in 0..m {
                        for b in 0..batch {
                            // SAFETY: as above.
                            unsafe { *shared.get(at(q0, first + b)) = lines[b * m + q0] };
                        }
                    }
                }
            });
    }
}

/// Transforms the `H` columns of one plane (`data[c + q1 H]`, `q1 < M`),
/// gathered [`BATCH`] at a time.
fn columns(data: &mut [Complex<f64>], h: usize, m: usize, fft: &dyn Fft<f64>, slot: &mut Slot) {
    for first in (0..h).step_by(BATCH) {
        let batch = BATCH.min(h - first);
        let lines = &mut slot.lines[..batch * m];
        for k in 0..m {
            for b in 0..batch {
                lines[b * m + k] = data[first + b + k * h];
            }
        }
        fft.process_with_scratch(lines, &mut slot.scratch);
        for k in 0..m {
            for b in 0..batch {
                data[first + b + k * h] = lines[b * m + k];
            }
        }
    }
}
