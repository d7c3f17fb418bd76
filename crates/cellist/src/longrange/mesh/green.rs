//! The mesh's Green's functions in Fourier space, `hat phi(q) = P(q) F(q)` and
//! `hat acc_a(q) = i A_a(q) F(q)` with `F` the transformed mesh masses; `P` and
//! `A_a` carry the inverse transform's `1/M^3`.

use super::fft::Fft3;
use super::slab::{Exchange, Slab};
use crate::interactions::GravityLaw;
use crate::threads::Threads;
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use std::f64::consts::PI;
use std::ops::Range;

/// Mean of `1/r` over the unit cube centred on `r = 0`: the cell-averaged
/// potential kernel at zero separation when there is no softening.
const CUBE_MEAN_INV_R: f64 = 2.380_077_2;

/// How much of the law a mesh carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Reach {
    /// All of it: `phi(r) = -G / sqrt(r^2 + eps^2)`.
    Full,
    /// The long-range part for the splitting radius `r_s` (in mesh cells):
    /// isolated, `phi(r) = -G erf(s / (2 r_s)) / s` with `s^2 = r^2 + eps^2`, so
    /// that the mesh carries the whole softened law beyond the split; periodic,
    /// `-4 pi G / k^2 exp(-k^2 r_s^2)` in Fourier space (`eps = 0`).
    Long {
        /// `r_s / h`.
        cells: f64,
    },
}

/// `(phi, k)` of a unit source at distance `r` (or `s`) under the long-range kernel with
/// splitting radius `r_s`: `phi = -G erf(x) / r` and
/// `k = G (erf x - 2x/sqrt(pi) exp(-x^2)) / r^3`, `x = r / (2 r_s)`, the
/// acceleration being `k (x_j - x_i)`. Small `x` uses the series
/// `phi = -G/(r_s sqrt pi) (1 - x^2/3)`, `k = G/(6 r_s^3 sqrt pi) (1 - 3 x^2/5)`.
#[inline]
pub(crate) fn long_pair(g: f64, r_s: f64, r: f64) -> (f64, f64) {
    let x = r / (2.0 * r_s);
    let root_pi = PI.sqrt();
    if x < 1e-3 {
        let x2 = x * x;
        (
            -g / (r_s * root_pi) * (1.0 - x2 / 3.0),
            g / (6.0 * r_s * r_s * r_s * root_pi) * (1.0 - 0.6 * x2),
        )
    } else {
        let erf = libm::erf(x);
        (
            -g * erf / r,
            g * (erf - 2.0 * x / root_pi * (-x * x).exp()) / (r * r * r),
        )
    }
}

/// `P`, `A_a` on a rank's columns of the half spectrum of an `M^3` mesh (`M`
/// rows of them), and the mesh's own potential kernel at the offsets a
/// particle's cloud has with itself.
pub(crate) struct Spectra {
    /// `P(q)`, real.
    pub(crate) phi: Vec<f64>,
    /// `A_a(q)`, real.
    pub(crate) acc: [Vec<f64>; 3],
    /// `g_c`: the mesh potential kernel at offset `(1,..,1,0,..)` with `c` ones.
    pub(crate) own: [f64; 4],
}

/// The signed frequency (or offset) of index `q` on a mesh of side `m`:
/// `q` for `q <= m/2`, else `q - m`.
pub(super) fn signed(q: usize, m: usize) -> f64 {
    if q <= m / 2 {
        q as f64
    } else {
        q as f64 - m as f64
    }
}

/// The deconvolution term of the isolated long-range Green's function,
/// `(1/W^2 - 1)` times the kernel's continuous transform on the mesh's
/// frequencies, scaled like `P` and `A_a` (`/ (h^3 M^3)`): that transform is
/// `-4 pi G exp(-k^2 r_s^2) / k^2` for `component` 0 (phi) and `-k_a` times it
/// for `component` `a` (acc; zero on the Nyquist plane of `a`). At `k = 0`,
/// `1/W^2 - 1 ~ k^2 h^2 / 6` leaves the limit `-4 pi G h^2 / 6` for phi.
fn deconvolution(g: f64, r_s: f64, cell: f64, q: [usize; 3], m: usize, component: usize) -> f64 {
    let scale = 1.0 / (cell * cell * cell * (m * m * m) as f64);
    let k = q.map(|qa| 2.0 * PI * signed(qa, m) / (m as f64 * cell));
    let k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
    if k2 == 0.0 {
        return if component == 0 {
            -4.0 * PI * g * cell * cell / 6.0 * scale
        } else {
            0.0
        };
    }
    let phi = (1.0 / cic_window2(q, m) - 1.0) * -4.0 * PI * g * (-k2 * r_s * r_s).exp() / k2;
    scale
        * match component {
            0 => phi,
            a if q[a - 1] == m / 2 => 0.0,
            a => -k[a - 1] * phi,
        }
}

/// `W(q)^2` of cloud-in-cell, assigned and interpolated:
/// `prod_a sinc^4(pi q_a / M)`.
fn cic_window2(q: [usize; 3], m: usize) -> f64 {
    q.iter()
        .map(|&qa| {
            let x = PI * signed(qa, m) / m as f64;
            if x == 0.0 {
                1.0
            } else {
                (x.sin() / x).powi(4)
            }
        })
        .product()
}

/// `(P, [A_0, A_1, A_2])` of the periodic box of side `length` on an `M^3` mesh
/// at mode `q`: `P = -4 pi G / (k^2 L^3)` (times `exp(-k^2 r_s^2) / W^2` for the
/// long range), `A_a = -k_a P` (zero on the Nyquist plane of axis `a`), both zero
/// at `k = 0`.
fn periodic_mode(
    law: &GravityLaw,
    reach: Reach,
    length: f64,
    m: usize,
    q: [usize; 3],
) -> (f64, [f64; 3]) {
    let volume = length * length * length;
    let k = q.map(|qa| 2.0 * PI * signed(qa, m) / length);
    let k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
    let mut v = if k2 == 0.0 {
        0.0
    } else {
        -4.0 * PI * law.g() / (k2 * volume)
    };
    if let Reach::Long { cells } = reach {
        let r_s = cells * (length / m as f64);
        v *= (-k2 * r_s * r_s).exp() / cic_window2(q, m);
    }
    let acc = std::array::from_fn(|a| if q[a] == m / 2 { 0.0 } else { -k[a] * v });
    (v, acc)
}

/// The mode `q = (q0, q1, q2)` of column `c = q1 H + q2` of an `M^3` mesh's
/// half spectrum.
pub(super) fn mode(q0: usize, c: usize, m: usize) -> [usize; 3] {
    let h = m / 2 + 1;
    [q0, c / h, c % h]
}

impl Spectra {
    /// Zeroed spectra of `len` modes (a rank's columns of every plane).
    pub(crate) fn new(len: usize) -> Self {
        Spectra {
            phi: vec![0.0; len],
            acc: std::array::from_fn(|_| vec![0.0; len]),
            own: [0.0; 4],
        }
    }

    /// The periodic box of side `length` on an `M^3` mesh ([`periodic_mode`]),
    /// at the modes of `columns` of every plane; the own kernel from every
    /// mode, so that it has the same bits on every rank.
    pub(crate) fn periodic(
        &mut self,
        law: &GravityLaw,
        reach: Reach,
        length: f64,
        m: usize,
        columns: Range<usize>,
    ) {
        let width = columns.len();
        let Spectra { phi, acc, .. } = self;
        let [ax, ay, az] = acc;
        phi.par_chunks_mut(width)
            .zip(ax.par_chunks_mut(width))
            .zip(ay.par_chunks_mut(width))
            .zip(az.par_chunks_mut(width))
            .enumerate()
            .for_each(|(q0, (((p, a0), a1), a2))| {
                for (k, c) in columns.clone().enumerate() {
                    let (v, a) = periodic_mode(law, reach, length, m, mode(q0, c, m));
                    p[k] = v;
                    [a0[k], a1[k], a2[k]] = a;
                }
            });
        let h = m / 2 + 1;
        self.own = own_kernel(m, 0..m * h, |q0, c| {
            periodic_mode(law, reach, length, m, mode(q0, c, m)).0
        });
    }

    /// The isolated mesh of cell `cell` zero-padded to `M^3`: `P` and `A_a` are
    /// the transforms of the real-space kernels `phi(r)` and `-k(r) d_a` of
    /// [`Reach`] on the offsets `d = h (o0, o1, o2)`, `-M/2 < o_a < M/2` (zero on
    /// the `o_a = -M/2` planes, which no pair of the unpadded `M/2` mesh reaches),
    /// divided by `M^3`. The long range is deconvolved by adding
    /// `(1/W^2 - 1)` times its continuous transform ([`deconvolution`]), not by
    /// dividing the sampled one by `W^2`: the latter would amplify the ringing of
    /// the kernel's cut at the padded box's edge. That transform is the unsoftened
    /// one: the softening changes it at `k ~ 1/eps`, where `1 - W^2` is small
    /// unless `eps` is below a cell, and then `exp(-k^2 r_s^2)` is. The modes are
    /// `slab`'s columns, transformed over its ranks; `work` is scratch.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn isolated(
        &mut self,
        law: &GravityLaw,
        reach: Reach,
        cell: f64,
        slab: &mut Slab<Fft3>,
        work: &mut [Complex<f64>],
        exchange: &dyn Exchange,
        threads: &Threads,
    ) {
        let m = slab.size();
        let columns = slab.columns();
        let width = columns.len();
        let (g, eps2) = (law.g(), law.softening2());
        // (phi, k) of a unit source at distance r
        let pair = move |r2: f64| match reach {
            Reach::Full => {
                let s2 = r2 + eps2;
                if r2 == 0.0 {
                    // bodies sharing a node: the cube's mean 1/r unless the
                    // softening is wider (a sample -G/eps would make every
                    // same-cell pair as deep as a pair at distance eps)
                    (-g * (CUBE_MEAN_INV_R / cell).min(1.0 / s2.sqrt()), 0.0)
                } else {
                    let inv = 1.0 / s2.sqrt();
                    (-g * inv, g * inv * inv * inv)
                }
            }
            Reach::Long { cells } => long_pair(g, cells * cell, (r2 + eps2).sqrt()),
        };
        let norm = 1.0 / (m * m * m) as f64;
        for component in 0..4 {
            let sample = |i: usize, j: usize, row: &mut [f64]| {
                let (di, dj) = (signed(i, m), signed(j, m));
                for (l, v) in row.iter_mut().enumerate() {
                    let d = [di, dj, signed(l, m)].map(|o| o * cell);
                    let edge = [i, j, l].contains(&(m / 2));
                    let (p, k) = pair(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                    *v = match (edge, component) {
                        (true, _) => 0.0,
                        (false, 0) => p,
                        (false, a) => -k * d[a - 1],
                    };
                }
            };
            slab.forward(m, work, sample, exchange, threads);
            // phi's transform is real, acc_a's imaginary
            let (out, imaginary) = match component {
                0 => (&mut self.phi, false),
                a => (&mut self.acc[a - 1], true),
            };
            let work = &*work;
            let columns = columns.clone();
            threads.install(|| {
                out.par_chunks_mut(width)
                    .zip(work.par_chunks(width))
                    .enumerate()
                    .for_each(|(q0, (o, w))| {
                        for (k, c) in columns.clone().enumerate() {
                            let v = if imaginary { w[k].im } else { w[k].re };
                            o[k] = v * norm;
                            if let Reach::Long { cells } = reach {
                                let q = mode(q0, c, m);
                                o[k] += deconvolution(g, cells * cell, cell, q, m, component);
                            }
                        }
                    })
            });
        }
        let phi = &self.phi;
        let start = columns.start;
        let mine = own_kernel(m, columns, |q0, c| phi[q0 * width + c - start]);
        self.own = slab.sum(mine, exchange);
    }
}

/// `g_c = sum_q P(q) cos(2 pi q.o_c / M)` over the modes of `columns` of every
/// plane (`phi(q0, c)`), with the half spectrum's `0 < q2 < M/2` terms doubled
/// (`P` is even), `o_c` the first `c` axes set to 1: over every column, the
/// mesh's own potential kernel at the offsets of a cloud with itself.
fn own_kernel(m: usize, columns: Range<usize>, phi: impl Fn(usize, usize) -> f64) -> [f64; 4] {
    let cos: Vec<f64> = (0..m)
        .map(|q| (2.0 * PI * q as f64 / m as f64).cos())
        .collect();
    let mut own = [0.0; 4];
    for q0 in 0..m {
        for c in columns.clone() {
            let [_, q1, q2] = mode(q0, c, m);
            let weight = if q2 == 0 || q2 == m / 2 { 1.0 } else { 2.0 };
            let v = weight * phi(q0, c);
            own[0] += v;
            own[1] += v * cos[q0];
            own[2] += v * cos[q0] * cos[q1];
            own[3] += v * cos[q0] * cos[q1] * cos[q2];
        }
    }
    own
}
