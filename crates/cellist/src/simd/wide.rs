//! Eight `f64` lanes: one AVX-512 register when the build targets AVX-512F,
//! two [`F64x4`](super::F64x4) otherwise. Its operations are those of
//! [`Register`], each the IEEE operation lane by lane (so the two
//! implementations give the same bits), except `mul_add` and `neg_mul_add`
//! (rounded once with FMA) and `inverse_sqrt`: in a build for AVX-512 the
//! 14-bit estimate `y_0` refined in one step by the series of
//! `(1 - e)^(-1/2)` to its fourth term,
//! `y = y_0 + y_0 e (1/2 + 3/8 e + 5/16 e^2)` with `e = 1 - x y_0^2`
//! (`|e|` about `2^-13` at most, so the series' rest `35/128 e^4` is about
//! `6e-17`: within a few ulp, not correctly rounded; `x = 0` and `x = inf`
//! give NaN), otherwise
//! `1 / sqrt(x)` exactly rounded.

use super::Register;

/// `((l0 + l1) + (l2 + l3)) + ((l4 + l5) + (l6 + l7))`: the lanes added across
/// in the order both implementations use.
#[inline(always)]
fn sum_of(l: [f64; 8]) -> f64 {
    ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]))
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
mod register {
    use super::{sum_of, Register};
    use std::arch::x86_64::*;

    /// Eight `f64` in one AVX-512 register.
    #[derive(Clone, Copy, Debug)]
    pub struct F64x8(__m512d);

    // SAFETY (every intrinsic below): the module is compiled only when the
    // target has AVX-512F, and loads/stores check the slice length first.
    impl Register for F64x8 {
        const WIDTH: usize = 8;
        #[inline(always)]
        fn splat(v: f64) -> Self {
            unsafe { F64x8(_mm512_set1_pd(v)) }
        }
        #[inline(always)]
        fn load(s: &[f64]) -> Self {
            assert!(s.len() >= 8);
            unsafe { F64x8(_mm512_loadu_pd(s.as_ptr())) }
        }
        #[inline(always)]
        fn store(self, s: &mut [f64]) {
            assert!(s.len() >= 8);
            unsafe { _mm512_storeu_pd(s.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn mul_add(self, b: Self, c: Self) -> Self {
            unsafe { F64x8(_mm512_fmadd_pd(self.0, b.0, c.0)) }
        }
        #[inline(always)]
        fn neg_mul_add(self, b: Self, c: Self) -> Self {
            unsafe { F64x8(_mm512_fnmadd_pd(self.0, b.0, c.0)) }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            unsafe { F64x8(_mm512_sqrt_pd(self.0)) }
        }
        /// The 14-bit estimate refined by its series (module doc).
        #[inline(always)]
        fn inverse_sqrt(self) -> Self {
            unsafe {
                let y = _mm512_rsqrt14_pd(self.0);
                let e = _mm512_fnmadd_pd(_mm512_mul_pd(self.0, y), y, _mm512_set1_pd(1.0));
                let c = _mm512_fmadd_pd(e, _mm512_set1_pd(5.0 / 16.0), _mm512_set1_pd(3.0 / 8.0));
                let c = _mm512_fmadd_pd(e, c, _mm512_set1_pd(0.5));
                F64x8(_mm512_fmadd_pd(_mm512_mul_pd(y, e), c, y))
            }
        }
        #[inline(always)]
        fn sum(self) -> f64 {
            let mut l = [0.0; 8];
            self.store(&mut l);
            sum_of(l)
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl std::ops::$trait for F64x8 {
                type Output = F64x8;
                #[inline(always)]
                fn $method(self, b: F64x8) -> F64x8 {
                    unsafe { F64x8($intrinsic(self.0, b.0)) }
                }
            }
        };
    }
    binary!(Add, add, _mm512_add_pd);
    binary!(Sub, sub, _mm512_sub_pd);
    binary!(Mul, mul, _mm512_mul_pd);
    binary!(Div, div, _mm512_div_pd);

    impl F64x8 {
        /// `if a < b { then } else { otherwise }`, lane by lane (false
        /// where either is NaN).
        #[inline(always)]
        pub fn select_less(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
            unsafe {
                let less = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a.0, b.0);
                F64x8(_mm512_mask_blend_pd(less, otherwise.0, then.0))
            }
        }

        /// The 8 x 8 transpose: lane `i` of `out[j]` is lane `j` of
        /// `rows[i]` (moves only: every bit kept). Pairs of lanes are
        /// swapped between rows, then pairs of pairs, then halves.
        #[inline(always)]
        pub fn transpose(rows: [Self; 8]) -> [Self; 8] {
            unsafe {
                let r = rows.map(|r| r.0);
                // s[2k] = [r_{2k,0} r_{2k+1,0} r_{2k,2} r_{2k+1,2} ...], s[2k + 1] the odd lanes
                let s: [__m512d; 8] = std::array::from_fn(|k| {
                    let (a, b) = (r[k & !1], r[k | 1]);
                    if k % 2 == 0 {
                        _mm512_unpacklo_pd(a, b)
                    } else {
                        _mm512_unpackhi_pd(a, b)
                    }
                });
                let low_pairs = _mm512_setr_epi64(0, 1, 8, 9, 4, 5, 12, 13);
                let high_pairs = _mm512_setr_epi64(2, 3, 10, 11, 6, 7, 14, 15);
                // u[4h + c]: lanes c and c + 4 of rows 4h..4h + 4
                let u: [__m512d; 8] = std::array::from_fn(|k| {
                    let (h, c) = (k / 4, k % 4);
                    let pairs = if c < 2 { low_pairs } else { high_pairs };
                    _mm512_permutex2var_pd(s[4 * h + c % 2], pairs, s[4 * h + 2 + c % 2])
                });
                let low_half = _mm512_setr_epi64(0, 1, 2, 3, 8, 9, 10, 11);
                let high_half = _mm512_setr_epi64(4, 5, 6, 7, 12, 13, 14, 15);
                std::array::from_fn(|j| {
                    let half = if j < 4 { low_half } else { high_half };
                    F64x8(_mm512_permutex2var_pd(u[j % 4], half, u[4 + j % 4]))
                })
            }
        }
    }
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
mod register {
    use super::{sum_of, Register};
    use crate::simd::F64x4;

    /// Eight `f64` as two [`F64x4`].
    #[derive(Clone, Copy, Debug)]
    pub struct F64x8([F64x4; 2]);

    impl F64x8 {
        /// `f` on both halves.
        #[inline(always)]
        fn halves(self, b: Self, c: Self, f: impl Fn(F64x4, F64x4, F64x4) -> F64x4) -> Self {
            F64x8([f(self.0[0], b.0[0], c.0[0]), f(self.0[1], b.0[1], c.0[1])])
        }
    }

    impl Register for F64x8 {
        const WIDTH: usize = 8;
        #[inline(always)]
        fn splat(v: f64) -> Self {
            F64x8([F64x4::splat(v); 2])
        }
        #[inline(always)]
        fn load(s: &[f64]) -> Self {
            assert!(s.len() >= 8);
            F64x8([F64x4::load(&s[..4]), F64x4::load(&s[4..8])])
        }
        #[inline(always)]
        fn store(self, s: &mut [f64]) {
            assert!(s.len() >= 8);
            let (low, high) = s.split_at_mut(4);
            self.0[0].store(low);
            self.0[1].store(high);
        }
        #[inline(always)]
        fn mul_add(self, b: Self, c: Self) -> Self {
            self.halves(b, c, F64x4::mul_add)
        }
        #[inline(always)]
        fn neg_mul_add(self, b: Self, c: Self) -> Self {
            self.halves(b, c, F64x4::neg_mul_add)
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            self.halves(self, self, |a, _, _| a.sqrt())
        }
        /// Exactly rounded (no AVX-512 in this build).
        #[inline(always)]
        fn inverse_sqrt(self) -> Self {
            self.halves(self, self, |a, _, _| a.inverse_sqrt())
        }
        #[inline(always)]
        fn sum(self) -> f64 {
            let mut l = [0.0; 8];
            self.store(&mut l);
            sum_of(l)
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident) => {
            impl std::ops::$trait for F64x8 {
                type Output = F64x8;
                #[inline(always)]
                fn $method(self, b: F64x8) -> F64x8 {
                    self.halves(b, b, |p, q, _| std::ops::$trait::$method(p, q))
                }
            }
        };
    }
    binary!(Add, add);
    binary!(Sub, sub);
    binary!(Mul, mul);
    binary!(Div, div);

    impl F64x8 {
        /// `if a < b { then } else { otherwise }`, lane by lane (false
        /// where either is NaN).
        #[inline(always)]
        pub fn select_less(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
            let half = |k: usize| F64x4::select_less(a.0[k], b.0[k], then.0[k], otherwise.0[k]);
            F64x8([half(0), half(1)])
        }

        /// The 8 x 8 transpose: lane `i` of `out[j]` is lane `j` of
        /// `rows[i]`.
        #[inline(always)]
        pub fn transpose(rows: [Self; 8]) -> [Self; 8] {
            let mut lanes = [[0.0; 8]; 8];
            for (row, lane) in rows.iter().zip(&mut lanes) {
                row.store(lane);
            }
            std::array::from_fn(|j| Self::load(&lanes.map(|lane| lane[j])))
        }
    }
}

pub use register::F64x8;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::F64x4;

    fn lanes(v: F64x8) -> [f64; 8] {
        let mut out = [0.0; 8];
        v.store(&mut out);
        out
    }

    /// Each operation is the scalar one lane by lane (the fused ones those
    /// of four lanes), and the sum adds in its stated order.
    #[test]
    fn eight_lanes_do_what_four_do() {
        let a: Vec<f64> = (0..8).map(|k| 1.0 + 0.37 * f64::from(k)).collect();
        let b: Vec<f64> = (0..8).map(|k| 2.5 - 0.11 * f64::from(k)).collect();
        let (x, y) = (F64x8::load(&a), F64x8::load(&b));
        let bits = |v: F64x8| lanes(v).map(f64::to_bits);
        let each = |f: &dyn Fn(f64, f64) -> f64| std::array::from_fn(|l| f(a[l], b[l]).to_bits());
        assert_eq!(bits(x + y), each(&|p, q| p + q));
        assert_eq!(bits(x - y), each(&|p, q| p - q));
        assert_eq!(bits(x * y), each(&|p, q| p * q));
        assert_eq!(bits(x / y), each(&|p, q| p / q));
        assert_eq!(bits(x.sqrt()), each(&|p, _| p.sqrt()));
        let (one, two) = (F64x8::splat(1.0), F64x8::splat(2.0));
        let pick = |p: f64, q: f64| if p < q { 1.0 } else { 2.0 };
        assert_eq!(bits(F64x8::select_less(x, y, one, two)), each(&pick));
        let four = |f: &dyn Fn(F64x4, F64x4) -> F64x4| -> [u64; 8] {
            let low = f(F64x4::load(&a[..4]), F64x4::load(&b[..4])).to_array();
            let high = f(F64x4::load(&a[4..]), F64x4::load(&b[4..])).to_array();
            std::array::from_fn(|l| if l < 4 { low[l] } else { high[l - 4] }.to_bits())
        };
        assert_eq!(bits(x.mul_add(y, x)), four(&|p, q| p.mul_add(q, p)));
        assert_eq!(bits(x.neg_mul_add(y, x)), four(&|p, q| p.neg_mul_add(q, p)));
        let sum = ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]));
        assert_eq!(x.sum().to_bits(), sum.to_bits());
        let mut out = [0.0; 9];
        x.store(&mut out[1..]);
        assert_eq!(&out[1..], &a[..]);
    }

    /// Lane `i` of the transpose's row `j` is lane `j` of row `i`, bit for bit.
    #[test]
    fn transposes_swap_rows_and_lanes() {
        let value = |i: usize, j: usize| (i * 8 + j) as f64 * 1.25 - 3.0;
        let rows: [F64x8; 8] = std::array::from_fn(|i| {
            F64x8::load(&std::array::from_fn::<f64, 8, _>(|j| value(i, j)))
        });
        let out = F64x8::transpose(rows);
        for (j, column) in out.into_iter().enumerate() {
            let got = lanes(column);
            for (i, v) in got.into_iter().enumerate() {
                assert_eq!(v.to_bits(), value(i, j).to_bits(), "lane {i} of row {j}");
            }
        }
        assert_eq!(
            F64x8::transpose(out).map(|r| lanes(r).map(f64::to_bits)),
            rows.map(|r| lanes(r).map(f64::to_bits))
        );
    }

    /// The inverse square root within 4 ulp of `1 / sqrt(x)` from `1e-200` to
    /// `1e200` (exactly it in a build without AVX-512).
    #[test]
    fn inverse_square_roots_are_within_a_few_ulp() {
        let mut worst = 0.0f64;
        for k in 0..4000 {
            let x = 10f64.powf(-200.0 + 0.1 * f64::from(k)) * (1.0 + 0.37 * f64::from(k % 7));
            let exact = 1.0 / x.sqrt();
            for got in lanes(F64x8::splat(x).inverse_sqrt()) {
                let error = ((got - exact) / exact).abs() / f64::EPSILON;
                assert!(error <= 4.0, "x {x}: {got} against {exact}");
                worst = worst.max(error);
            }
        }
        if cfg!(not(target_feature = "avx512f")) {
            assert_eq!(worst, 0.0);
        }
    }
}
