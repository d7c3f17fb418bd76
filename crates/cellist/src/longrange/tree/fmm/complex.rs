//! The complex-variable expansions of the 2D fast multipole method
//! (Greengard and Rokhlin) for the Cauchy sum `f(z) = sum_j q_j / (z - z_j)`,
//! each scaled by its box's radius `s` so that no power over- or underflows:
//!
//! - multipole about `c`: `f(z) = sum_k a_k s^k / (z - c)^(k + 1)`,
//!   `a_k = sum_j q_j ((z_j - c) / s)^k` (P2M), valid for `|z - c| > s`;
//! - local about `t`: `f(z) = sum_l b_l ((z - t) / s)^l` (L2P), valid for
//!   `|z - t| < s` away from the sources that made it.
//!
//! The shifts follow from the binomial series of `1 / (w + d)^(k + 1)` and of
//! `(w + d)^l`; each function states its own formula.

use crate::simd::F64x4;
use rustfft::num_complex::Complex64;

/// The binomial coefficients `C(n, k)` for `n <= 2 p`, row by row, and
/// M2L's `C(k + l, k)` by `k`, four `l` at a time.
#[derive(Clone, Debug)]
pub(super) struct Binomials {
    order: usize,
    rows: Vec<Vec<f64>>,
    /// `C(k + l, k)` at `[k][l / 4]` lane `l % 4`, for `l` up to `p`
    /// rounded up to whole lanes (0 beyond `p`).
    m2l: Vec<Vec<F64x4>>,
}

impl Binomials {
    /// The table for expansions of `order` `p` (terms `0..=p`).
    pub fn new(order: usize) -> Self {
        let mut rows: Vec<Vec<f64>> = vec![vec![1.0]];
        for n in 1..=2 * order {
            let last = &rows[n - 1];
            let row = (0..=n)
                .map(|k| {
                    let left = if k > 0 { last[k - 1] } else { 0.0 };
                    let right = if k < n { last[k] } else { 0.0 };
                    left + right
                })
                .collect();
            rows.push(row);
        }
        let blocks = (order + 1).div_ceil(4);
        let m2l = (0..=order)
            .map(|k| {
                (0..blocks)
                    .map(|b| {
                        let lanes: [f64; 4] = std::array::from_fn(|i| {
                            let l = 4 * b + i;
                            if l <= order {
                                rows[k + l][k]
                            } else {
                                0.0
                            }
                        });
                        F64x4::load(&lanes)
                    })
                    .collect()
            })
            .collect();
        Binomials { order, rows, m2l }
    }

    /// The expansions' order `p`.
    pub fn order(&self) -> usize {
        self.order
    }

    /// `C(n, k)`.
    #[inline(always)]
    fn get(&self, n: usize, k: usize) -> f64 {
        self.rows[n][k]
    }
}

/// P2M: adds `a_k += sum_j q_j ((z_j - c) / s)^k` for the sources `z` with
/// charges `q` (real multiples of `charge`) to `a` (`p + 1` terms).
pub(super) fn p2m(
    a: &mut [Complex64],
    centre: Complex64,
    scale: f64,
    sources: impl Iterator<Item = (Complex64, f64)>,
    charge: Complex64,
) {
    let inv = 1.0 / scale;
    for (z, q) in sources {
        let w = (z - centre) * inv;
        let mut power = charge * q;
        for term in a.iter_mut() {
            *term += power;
            power *= w;
        }
    }
}

/// M2M: adds the child's multipole `child` (about `c`, scale `s_c`) shifted to
/// the parent's centre `c'` and scale `s_p` to `parent`:
/// `a'_k += sum_{m <= k} C(k, m) a_m (s_c / s_p)^m ((c - c') / s_p)^(k - m)`.
pub(super) fn m2m(
    binomials: &Binomials,
    child: &[Complex64],
    child_centre: Complex64,
    child_scale: f64,
    parent: &mut [Complex64],
    parent_centre: Complex64,
    parent_scale: f64,
) {
    let p = binomials.order();
    let ratio = child_scale / parent_scale;
    let shift = (child_centre - parent_centre) / parent_scale;
    // scaled[m] = a_m ratio^m; shifts[j] = shift^j
    let mut scaled = [Complex64::new(0.0, 0.0); MAX_TERMS];
    let mut shifts = [Complex64::new(1.0, 0.0); MAX_TERMS];
    let mut r = 1.0;
    for m in 0..=p {
        scaled[m] = child[m] * r;
        r *= ratio;
        if m > 0 {
            shifts[m] = shifts[m - 1] * shift;
        }
    }
    for k in 0..=p {
        let mut sum = Complex64::new(0.0, 0.0);
        for m in 0..=k {
            sum += scaled[m] * shifts[k - m] * binomials.get(k, m);
        }
        parent[k] += sum;
    }
}

/// M2L: adds the local expansion about `t` (scale `s_t`) of the multipole `a`
/// about `c` (scale `s_c`) to `b`. With `d = t - c`, `rho = s_c / d` and
/// `tau = -s_t / d`:
/// `b_l += (tau^l / d) sum_k C(k + l, k) a_k rho^k`,
/// the sums over `k` for four `l` at a time in SIMD lanes.
pub(super) fn m2l(
    binomials: &Binomials,
    a: &[Complex64],
    source_centre: Complex64,
    source_scale: f64,
    b: &mut [Complex64],
    target_centre: Complex64,
    target_scale: f64,
) {
    let p = binomials.order();
    let d = target_centre - source_centre;
    let inv_d = d.inv();
    let rho = inv_d * source_scale;
    let tau = -inv_d * target_scale;
    let blocks = (p + 1).div_ceil(4);
    let mut re = [F64x4::splat(0.0); MAX_TERMS / 4];
    let mut im = [F64x4::splat(0.0); MAX_TERMS / 4];
    let mut power = Complex64::new(1.0, 0.0);
    for (ak, column) in a.iter().zip(&binomials.m2l).take(p + 1) {
        let u = *ak * power;
        power *= rho;
        let (ur, ui) = (F64x4::splat(u.re), F64x4::splat(u.im));
        for (j, c) in column.iter().enumerate().take(blocks) {
            re[j] = c.mul_add(ur, re[j]);
            im[j] = c.mul_add(ui, im[j]);
        }
    }
    let mut factor = inv_d;
    for (l, term) in b.iter_mut().enumerate().take(p + 1) {
        let (j, lane) = (l / 4, l % 4);
        let sum = Complex64::new(re[j].to_array()[lane], im[j].to_array()[lane]);
        *term += factor * sum;
        factor *= tau;
    }
}

/// L2L: adds the parent's local `b` (about `t`, scale `s_p`) shifted to the
/// child's centre `t'` and scale `s_c` to `child`:
/// `b'_m += sum_{l >= m} C(l, m) b_l ((t' - t) / s_p)^(l - m) (s_c / s_p)^m`.
pub(super) fn l2l(
    binomials: &Binomials,
    parent: &[Complex64],
    parent_centre: Complex64,
    parent_scale: f64,
    child: &mut [Complex64],
    child_centre: Complex64,
    child_scale: f64,
) {
    let p = binomials.order();
    let shift = (child_centre - parent_centre) / parent_scale;
    let ratio = child_scale / parent_scale;
    let mut shifts = [Complex64::new(1.0, 0.0); MAX_TERMS];
    for j in 1..=p {
        shifts[j] = shifts[j - 1] * shift;
    }
    let mut r = 1.0;
    for m in 0..=p {
        let mut sum = Complex64::new(0.0, 0.0);
        for l in m..=p {
            sum += parent[l] * shifts[l - m] * binomials.get(l, m);
        }
        child[m] += sum * r;
        r *= ratio;
    }
}

/// L2P: `sum_l b_l ((z - t) / s)^l` by Horner's rule.
#[inline]
pub(super) fn l2p(b: &[Complex64], centre: Complex64, scale: f64, z: Complex64) -> Complex64 {
    let w = (z - centre) / scale;
    b.iter()
        .rev()
        .fold(Complex64::new(0.0, 0.0), |sum, &term| sum * w + term)
}

/// The most terms an expansion has (`p <= MAX_TERMS - 1`).
pub(super) const MAX_TERMS: usize = super::ORDER_RANGE.1 + 1;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::Rng;

    fn cloud(rng: &mut Rng, centre: Complex64, half: f64, n: usize) -> Vec<(Complex64, f64)> {
        (0..n)
            .map(|_| {
                let z = centre
                    + Complex64::new(
                        half * (2.0 * rng.uniform() - 1.0),
                        half * (2.0 * rng.uniform() - 1.0),
                    );
                (z, rng.uniform() - 0.5)
            })
            .collect()
    }

    fn direct(sources: &[(Complex64, f64)], charge: Complex64, z: Complex64) -> Complex64 {
        sources.iter().map(|&(w, q)| charge * q / (z - w)).sum()
    }

    fn relative(got: Complex64, want: Complex64) -> f64 {
        (got - want).norm() / want.norm()
    }

    /// Every step of the chain P2M, M2M, M2L, L2L, L2P against the direct
    /// sum, at orders 10 and 20: the error falls with the order and is near
    /// the ratio of radius to distance to the power `p + 1`.
    #[test]
    fn the_chain_converges_with_the_order() {
        let mut rng = Rng::new(7);
        let charge = Complex64::new(0.3, -1.1);
        // a child box in its parent, far from a target box and its child
        let (parent_c, child_c) = (Complex64::new(0.0, 0.0), Complex64::new(0.25, -0.25));
        let (target_c, leaf_c) = (Complex64::new(4.0, 1.0), Complex64::new(3.75, 1.25));
        let sources = cloud(&mut rng, child_c, 0.25, 40);
        let targets: Vec<Complex64> = cloud(&mut rng, leaf_c, 0.25, 20)
            .into_iter()
            .map(|t| t.0)
            .collect();
        let (s_parent, s_child) = (0.5 * 2f64.sqrt(), 0.25 * 2f64.sqrt());
        let mut last = f64::INFINITY;
        for p in [10, 20] {
            let binomials = Binomials::new(p);
            let zero = vec![Complex64::new(0.0, 0.0); p + 1];
            let mut a_child = zero.clone();
            p2m(
                &mut a_child,
                child_c,
                s_child,
                sources.iter().copied(),
                charge,
            );
            let mut a_parent = zero.clone();
            m2m(
                &binomials,
                &a_child,
                child_c,
                s_child,
                &mut a_parent,
                parent_c,
                s_parent,
            );
            let mut b_target = zero.clone();
            m2l(
                &binomials,
                &a_parent,
                parent_c,
                s_parent,
                &mut b_target,
                target_c,
                s_parent,
            );
            let mut b_leaf = zero.clone();
            l2l(
                &binomials,
                &b_target,
                target_c,
                s_parent,
                &mut b_leaf,
                leaf_c,
                s_child,
            );
            let worst = targets
                .iter()
                .map(|&z| {
                    relative(
                        l2p(&b_leaf, leaf_c, s_child, z),
                        direct(&sources, charge, z),
                    )
                })
                .fold(0.0, f64::max);
            // (sqrt(2) / 2) / (|t - c| - sqrt(2) / 2) = 0.2 for the ratio
            let bound = 10.0 * 0.21f64.powi(p as i32 + 1);
            eprintln!("p {p}: worst relative error {worst:e} (bound {bound:e})");
            assert!(worst < bound && worst < last, "p {p}: {worst:e}");
            last = worst;
        }
    }

    #[test]
    fn binomials_are_pascals_triangle() {
        let b = Binomials::new(5);
        assert_eq!(b.get(10, 3), 120.0);
        assert_eq!(b.get(7, 0), 1.0);
        assert_eq!(b.get(7, 7), 1.0);
        assert_eq!(b.get(6, 2), 15.0);
    }
}
