//! Four `f64` lanes: AVX2 and FMA registers when the build targets them (the
//! project builds with `-C target-cpu=native`), plain arrays otherwise. The hot
//! loops of the long-range solvers and of the collision benchmark are written on
//! this type so that they run as SIMD without hoping for the auto-vectoriser;
//! [`F64x8`] (`simd/wide.rs`) holds eight, one AVX-512 register, for the
//! loops written on [`Register`] that gain from the wider registers.
//!
//! `+ - * /`, negation, `sqrt`, the comparisons, selects, rounding, the scaling
//! by `2^(k/4)` and the pair shuffles are exact IEEE binary64 operations lane
//! by lane in both implementations, so they give the same bits everywhere (the
//! collision benchmark depends on it); the tests compile both implementations
//! and compare them. [`Real`] lets a kernel be written once for `f64` and for
//! the lanes, with the bits of four scalar calls. What differs: `mul_add`
//! and `neg_mul_add` (a build with FMA rounds `a * b + c` once, one without it
//! twice) and `min` and `max` with a NaN lane ([`F64x8::inverse_sqrt`] is
//! an estimate in a build for AVX-512).

#[cfg(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
))]
mod lanes {
    use std::arch::x86_64::*;

    /// Four `f64` in one AVX register.
    #[derive(Clone, Copy, Debug)]
    pub struct F64x4(__m256d);

    // SAFETY (every intrinsic below): the module is compiled only when the target
    // has AVX2 and FMA, and loads/stores check the slice length first.
    impl F64x4 {
        /// All lanes `v`.
        #[inline(always)]
        pub fn splat(v: f64) -> Self {
            unsafe { F64x4(_mm256_set1_pd(v)) }
        }
        /// `s[0..4]`.
        #[inline(always)]
        pub fn load(s: &[f64]) -> Self {
            assert!(s.len() >= 4);
            unsafe { F64x4(_mm256_loadu_pd(s.as_ptr())) }
        }
        /// Writes the lanes to `s[0..4]`.
        #[inline(always)]
        pub fn store(self, s: &mut [f64]) {
            assert!(s.len() >= 4);
            unsafe { _mm256_storeu_pd(s.as_mut_ptr(), self.0) }
        }
        /// `self * b + c`, rounded once.
        #[inline(always)]
        pub fn mul_add(self, b: Self, c: Self) -> Self {
            unsafe { F64x4(_mm256_fmadd_pd(self.0, b.0, c.0)) }
        }
        /// `c - self * b`, rounded once.
        #[inline(always)]
        pub fn neg_mul_add(self, b: Self, c: Self) -> Self {
            unsafe { F64x4(_mm256_fnmadd_pd(self.0, b.0, c.0)) }
        }
        /// Lane-wise square root.
        #[inline(always)]
        pub fn sqrt(self) -> Self {
            unsafe { F64x4(_mm256_sqrt_pd(self.0)) }
        }
        /// `1 / sqrt(x)` lane by lane, exactly rounded (the estimate of
        /// eight lanes is [`F64x8`]'s).
        #[inline(always)]
        pub fn inverse_sqrt(self) -> Self {
            unsafe { F64x4(_mm256_div_pd(_mm256_set1_pd(1.0), _mm256_sqrt_pd(self.0))) }
        }
        /// `if a == b { zero } else { self }` lane by lane.
        #[inline(always)]
        pub fn zero_where_equal(self, a: Self, b: Self) -> Self {
            unsafe {
                F64x4(_mm256_andnot_pd(
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(a.0, b.0),
                    self.0,
                ))
            }
        }
        /// The lanes as an array.
        #[inline(always)]
        pub fn to_array(self) -> [f64; 4] {
            let mut out = [0.0; 4];
            self.store(&mut out);
            out
        }
        /// `if a < b { self } else { zero }` lane by lane.
        #[inline(always)]
        pub fn zero_unless_less(self, a: Self, b: Self) -> Self {
            unsafe { F64x4(_mm256_and_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(a.0, b.0), self.0)) }
        }
        /// Lane-wise minimum.
        #[inline(always)]
        pub fn min(self, b: Self) -> Self {
            unsafe { F64x4(_mm256_min_pd(self.0, b.0)) }
        }
        /// Rounded to the nearest integer, ties to even.
        #[inline(always)]
        pub fn round_ties_even(self) -> Self {
            unsafe {
                F64x4(_mm256_round_pd::<
                    { _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC },
                >(self.0))
            }
        }
        /// `if a < b { then } else { otherwise }` lane by lane.
        #[inline(always)]
        pub fn select_less(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
            unsafe {
                let less = _mm256_cmp_pd::<_CMP_LT_OQ>(a.0, b.0);
                F64x4(_mm256_blendv_pd(otherwise.0, then.0, less))
            }
        }
        /// Whether `a < b` in some lane.
        #[inline(always)]
        pub fn any_less(a: Self, b: Self) -> bool {
            Self::mask_less(a, b) != 0
        }
        /// Bit `l` set where `a < b` in lane `l`.
        #[inline(always)]
        pub fn mask_less(a: Self, b: Self) -> u32 {
            unsafe { _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(a.0, b.0)) as u32 }
        }
        /// Lane-wise maximum.
        #[inline(always)]
        pub fn max(self, b: Self) -> Self {
            unsafe { F64x4(_mm256_max_pd(self.0, b.0)) }
        }
        /// [`super::Real::times_two_to_quarters`] lane by lane:
        /// `QUARTER_POWERS[j]` by three blends (two levels) on the bits of `j`
        /// moved to the sign, `2^n` from the exponent field (the low 12 bits of `n + 1023`,
        /// the same for a logical shift as for the arithmetic one).
        #[inline(always)]
        pub fn times_two_to_quarters(self, rounded: Self) -> Self {
            unsafe {
                let k = _mm256_sub_epi64(
                    _mm256_castpd_si256(rounded.0),
                    _mm256_set1_epi64x(super::ROUNDER.to_bits() as i64),
                );
                let odd = _mm256_castsi256_pd(_mm256_slli_epi64::<63>(k));
                let upper = _mm256_castsi256_pd(_mm256_slli_epi64::<62>(k));
                let [p0, p1, p2, p3] = super::QUARTER_POWERS.map(|p| _mm256_set1_pd(p));
                let low = _mm256_blendv_pd(p0, p1, odd);
                let high = _mm256_blendv_pd(p2, p3, odd);
                let quarter = _mm256_blendv_pd(low, high, upper);
                let n = _mm256_srli_epi64::<2>(k);
                let two_n = _mm256_castsi256_pd(_mm256_slli_epi64::<52>(_mm256_add_epi64(
                    n,
                    _mm256_set1_epi64x(1023),
                )));
                F64x4(_mm256_mul_pd(_mm256_mul_pd(self.0, quarter), two_n))
            }
        }
        /// Four pairs `p[l] = [x_l, y_l]` as the lanes `x` and `y`.
        #[inline(always)]
        pub fn unzip_pairs(p: [[f64; 2]; 4]) -> (Self, Self) {
            unsafe {
                let pair = |l: usize| _mm_loadu_pd(p[l].as_ptr());
                // (x0, y0, x2, y2) and (x1, y1, x3, y3)
                let even = _mm256_insertf128_pd::<1>(_mm256_castpd128_pd256(pair(0)), pair(2));
                let odd = _mm256_insertf128_pd::<1>(_mm256_castpd128_pd256(pair(1)), pair(3));
                (
                    F64x4(_mm256_unpacklo_pd(even, odd)),
                    F64x4(_mm256_unpackhi_pd(even, odd)),
                )
            }
        }
        /// The inverse of [`F64x4::unzip_pairs`]: `[x_l, y_l]` for each lane `l`.
        #[inline(always)]
        pub fn zip_pairs(x: Self, y: Self) -> [[f64; 2]; 4] {
            unsafe {
                let even = _mm256_unpacklo_pd(x.0, y.0);
                let odd = _mm256_unpackhi_pd(x.0, y.0);
                let mut out = [[0.0; 2]; 4];
                _mm_storeu_pd(out[0].as_mut_ptr(), _mm256_castpd256_pd128(even));
                _mm_storeu_pd(out[1].as_mut_ptr(), _mm256_castpd256_pd128(odd));
                _mm_storeu_pd(out[2].as_mut_ptr(), _mm256_extractf128_pd::<1>(even));
                _mm_storeu_pd(out[3].as_mut_ptr(), _mm256_extractf128_pd::<1>(odd));
                out
            }
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl std::ops::$trait for F64x4 {
                type Output = F64x4;
                #[inline(always)]
                fn $method(self, b: F64x4) -> F64x4 {
                    unsafe { F64x4($intrinsic(self.0, b.0)) }
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_pd);
    binary!(Sub, sub, _mm256_sub_pd);
    binary!(Mul, mul, _mm256_mul_pd);
    binary!(Div, div, _mm256_div_pd);

    impl std::ops::Neg for F64x4 {
        type Output = F64x4;
        /// The sign bits flipped, as `-x` does.
        #[inline(always)]
        fn neg(self) -> F64x4 {
            unsafe { F64x4(_mm256_xor_pd(self.0, _mm256_set1_pd(-0.0))) }
        }
    }
}

#[cfg(any(
    test,
    not(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    ))
))]
// in test builds next to the AVX lanes: only the exact operations are compared
#[cfg_attr(test, allow(dead_code))]
mod portable {
    /// Four `f64` as an array.
    #[derive(Clone, Copy, Debug)]
    pub struct F64x4([f64; 4]);

    impl F64x4 {
        /// All lanes `v`.
        #[inline(always)]
        pub fn splat(v: f64) -> Self {
            F64x4([v; 4])
        }
        /// `s[0..4]`.
        #[inline(always)]
        pub fn load(s: &[f64]) -> Self {
            F64x4([s[0], s[1], s[2], s[3]])
        }
        /// Writes the lanes to `s[0..4]`.
        #[inline(always)]
        pub fn store(self, s: &mut [f64]) {
            s[..4].copy_from_slice(&self.0);
        }
        /// `self * b + c` (rounded twice).
        #[inline(always)]
        pub fn mul_add(self, b: Self, c: Self) -> Self {
            self * b + c
        }
        /// `c - self * b` (rounded twice).
        #[inline(always)]
        pub fn neg_mul_add(self, b: Self, c: Self) -> Self {
            c - self * b
        }
        /// Lane-wise square root.
        #[inline(always)]
        pub fn sqrt(self) -> Self {
            F64x4(self.0.map(f64::sqrt))
        }
        /// `1 / sqrt(x)` lane by lane, exactly rounded.
        #[inline(always)]
        pub fn inverse_sqrt(self) -> Self {
            F64x4(self.0.map(|x| 1.0 / x.sqrt()))
        }
        /// `if a == b { zero } else { self }` lane by lane.
        #[inline(always)]
        pub fn zero_where_equal(self, a: Self, b: Self) -> Self {
            F64x4(std::array::from_fn(|l| {
                if a.0[l] == b.0[l] {
                    0.0
                } else {
                    self.0[l]
                }
            }))
        }
        /// The lanes as an array.
        #[inline(always)]
        pub fn to_array(self) -> [f64; 4] {
            self.0
        }
        /// `if a < b { self } else { zero }` lane by lane.
        #[inline(always)]
        pub fn zero_unless_less(self, a: Self, b: Self) -> Self {
            F64x4(std::array::from_fn(|l| {
                if a.0[l] < b.0[l] {
                    self.0[l]
                } else {
                    0.0
                }
            }))
        }
        /// Lane-wise minimum.
        #[inline(always)]
        pub fn min(self, b: Self) -> Self {
            F64x4(std::array::from_fn(|l| self.0[l].min(b.0[l])))
        }
        /// Rounded to the nearest integer, ties to even.
        #[inline(always)]
        pub fn round_ties_even(self) -> Self {
            F64x4(self.0.map(f64::round_ties_even))
        }
        /// `if a < b { then } else { otherwise }` lane by lane.
        #[inline(always)]
        pub fn select_less(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
            F64x4(std::array::from_fn(|l| {
                if a.0[l] < b.0[l] {
                    then.0[l]
                } else {
                    otherwise.0[l]
                }
            }))
        }
        /// Whether `a < b` in some lane.
        #[inline(always)]
        pub fn any_less(a: Self, b: Self) -> bool {
            Self::mask_less(a, b) != 0
        }
        /// Bit `l` set where `a < b` in lane `l`.
        #[inline(always)]
        pub fn mask_less(a: Self, b: Self) -> u32 {
            (0..4).fold(0, |bits, l| bits | u32::from(a.0[l] < b.0[l]) << l)
        }
        /// Lane-wise maximum.
        #[inline(always)]
        pub fn max(self, b: Self) -> Self {
            F64x4(std::array::from_fn(|l| self.0[l].max(b.0[l])))
        }
        /// [`super::Real::times_two_to_quarters`] lane by lane.
        #[inline(always)]
        pub fn times_two_to_quarters(self, rounded: Self) -> Self {
            use super::Real;
            F64x4(std::array::from_fn(|l| {
                self.0[l].times_two_to_quarters(rounded.0[l])
            }))
        }
        /// Four pairs `p[l] = [x_l, y_l]` as the lanes `x` and `y`.
        #[inline(always)]
        pub fn unzip_pairs(p: [[f64; 2]; 4]) -> (Self, Self) {
            (F64x4(p.map(|q| q[0])), F64x4(p.map(|q| q[1])))
        }
        /// The inverse of [`F64x4::unzip_pairs`]: `[x_l, y_l]` for each lane `l`.
        #[inline(always)]
        pub fn zip_pairs(x: Self, y: Self) -> [[f64; 2]; 4] {
            std::array::from_fn(|l| [x.0[l], y.0[l]])
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident, $op:tt) => {
            impl std::ops::$trait for F64x4 {
                type Output = F64x4;
                #[inline(always)]
                fn $method(self, b: F64x4) -> F64x4 {
                    F64x4(std::array::from_fn(|l| self.0[l] $op b.0[l]))
                }
            }
        };
    }
    binary!(Add, add, +);
    binary!(Sub, sub, -);
    binary!(Mul, mul, *);
    binary!(Div, div, /);

    impl std::ops::Neg for F64x4 {
        type Output = F64x4;
        #[inline(always)]
        fn neg(self) -> F64x4 {
            F64x4(self.0.map(|v| -v))
        }
    }
}

#[cfg(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
))]
pub use lanes::F64x4;
#[cfg(not(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
)))]
pub use portable::F64x4;

mod wide;
pub use wide::F64x8;

/// A SIMD register of `WIDTH` `f64` lanes ([`F64x4`], [`F64x8`]): what a pair
/// loop written once for either width needs. The operations are the lanes'
/// own (see [`F64x4`]); `sum` adds the lanes across in a fixed order.
pub trait Register:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
{
    /// The number of lanes.
    const WIDTH: usize;
    /// `v` in every lane.
    fn splat(v: f64) -> Self;
    /// `s[0..WIDTH]`.
    fn load(s: &[f64]) -> Self;
    /// Writes the lanes to `s[0..WIDTH]`.
    fn store(self, s: &mut [f64]);
    /// `self * b + c` (rounded once with FMA).
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// `c - self * b` (rounded once with FMA).
    fn neg_mul_add(self, b: Self, c: Self) -> Self;
    /// Lane-wise square root.
    fn sqrt(self) -> Self;
    /// `1 / sqrt(x)`: exactly rounded, or within a few ulp for
    /// [`F64x8`] in a build for AVX-512.
    fn inverse_sqrt(self) -> Self;
    /// The lanes added across, pairwise in a fixed order.
    fn sum(self) -> f64;
}

impl Register for F64x4 {
    const WIDTH: usize = 4;
    #[inline(always)]
    fn splat(v: f64) -> Self {
        F64x4::splat(v)
    }
    #[inline(always)]
    fn load(s: &[f64]) -> Self {
        F64x4::load(s)
    }
    #[inline(always)]
    fn store(self, s: &mut [f64]) {
        F64x4::store(self, s)
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        F64x4::mul_add(self, b, c)
    }
    #[inline(always)]
    fn neg_mul_add(self, b: Self, c: Self) -> Self {
        F64x4::neg_mul_add(self, b, c)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F64x4::sqrt(self)
    }
    #[inline(always)]
    fn inverse_sqrt(self) -> Self {
        F64x4::inverse_sqrt(self)
    }
    /// `(l0 + l1) + (l2 + l3)`.
    #[inline(always)]
    fn sum(self) -> f64 {
        F64x4::sum(self)
    }
}

/// `[f(0), f(1), f(2)]`, always inlined: a hot loop's per-axis arrays (an
/// array's `map` was left a call in the pair loops, and a call there spills
/// every vector register the loop holds).
#[inline(always)]
pub fn axes<T>(f: impl Fn(usize) -> T) -> [T; 3] {
    [f(0), f(1), f(2)]
}

/// The number types a kernel is written once for: `f64` and [`F64x4`], whose
/// lanes do the same IEEE operations, so that four lanes give the bits of four
/// scalar calls (for [`Real::max`], as long as `b` is neither NaN nor zero).
pub trait Real:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
{
    /// `v` (in every lane).
    fn splat(v: f64) -> Self;
    /// `max(self, b)`, and `b` where `self` is NaN. Where `b` is NaN, or both
    /// are zeros of either sign, `f64` and the lanes may differ: callers pass a
    /// `b` that is neither.
    fn max(self, b: Self) -> Self;
    /// `if a < b { then } else { otherwise }` (per lane).
    fn select_less(a: Self, b: Self, then: Self, otherwise: Self) -> Self;
    /// `self * b + c`: rounded once with AVX2 and FMA, twice without (in `f64`
    /// as in the lanes, so that they give the same bits).
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// `self * 2^(k/4)` as `self * 2^(j/4) * 2^n` (the products in that
    /// order), where the integer `k = 4n + j` (`j` in `0..4`) is held by
    /// `rounded = k + ROUNDER` (its bit pattern minus that of [`ROUNDER`]),
    /// `2^(j/4)` is [`QUARTER_POWERS`]`[j]` and `2^n` is built from its
    /// exponent bits (`-1022 <= n <= 1023`): the last step of an exponential.
    fn times_two_to_quarters(self, rounded: Self) -> Self;
}

/// `1.5 * 2^52`: adding it to a number below `2^51` in magnitude rounds it to
/// an integer, held in the low bits of the sum's mantissa.
pub const ROUNDER: f64 = 6_755_399_441_055_744.0;
/// `2^(j/4)` for `j = 0..3`.
pub const QUARTER_POWERS: [f64; 4] = [
    1.0,
    1.189_207_115_002_721,
    std::f64::consts::SQRT_2,
    1.681_792_830_507_429,
];

impl Real for f64 {
    #[inline(always)]
    fn splat(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn max(self, b: Self) -> Self {
        f64::max(self, b)
    }
    #[inline(always)]
    fn select_less(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
        if a < b {
            then
        } else {
            otherwise
        }
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        if cfg!(all(
            target_arch = "x86_64",
            target_feature = "avx2",
            target_feature = "fma"
        )) {
            f64::mul_add(self, b, c)
        } else {
            self * b + c
        }
    }
    /// `2^(j/4)` picked by selects between constants (no table lookup: with
    /// the powers passed in as an array, they became one indexed load, which
    /// kept loops of it from vectorising).
    #[inline(always)]
    fn times_two_to_quarters(self, rounded: Self) -> Self {
        let k = (rounded.to_bits() as i64).wrapping_sub(ROUNDER.to_bits() as i64);
        let (n, j) = (k >> 2, k & 3);
        let low = if j & 1 == 0 {
            QUARTER_POWERS[0]
        } else {
            QUARTER_POWERS[1]
        };
        let high = if j & 1 == 0 {
            QUARTER_POWERS[2]
        } else {
            QUARTER_POWERS[3]
        };
        let quarter = if j & 2 == 0 { low } else { high };
        let two_n = f64::from_bits((n + 1023).wrapping_shl(52) as u64);
        self * quarter * two_n
    }
}

impl Real for F64x4 {
    #[inline(always)]
    fn splat(v: f64) -> Self {
        F64x4::splat(v)
    }
    #[inline(always)]
    fn max(self, b: Self) -> Self {
        F64x4::max(self, b)
    }
    #[inline(always)]
    fn select_less(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
        F64x4::select_less(a, b, then, otherwise)
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        F64x4::mul_add(self, b, c)
    }
    #[inline(always)]
    fn times_two_to_quarters(self, rounded: Self) -> Self {
        F64x4::times_two_to_quarters(self, rounded)
    }
}

impl F64x4 {
    /// The lanes summed in a fixed order, `(l0 + l1) + (l2 + l3)`.
    #[inline(always)]
    pub fn sum(self) -> f64 {
        let l = self.to_array();
        (l[0] + l[1]) + (l[2] + l[3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_do_what_they_say() {
        let a = F64x4::load(&[1.0, 4.0, 9.0, 16.0]);
        let b = F64x4::splat(2.0);
        assert_eq!((a + b).to_array(), [3.0, 6.0, 11.0, 18.0]);
        assert_eq!((a - b).to_array(), [-1.0, 2.0, 7.0, 14.0]);
        assert_eq!((a * b).to_array(), [2.0, 8.0, 18.0, 32.0]);
        assert_eq!((a / b).to_array(), [0.5, 2.0, 4.5, 8.0]);
        assert_eq!(a.sqrt().to_array(), [1.0, 2.0, 3.0, 4.0]);
        assert_eq!(a.mul_add(b, b).to_array(), [4.0, 10.0, 20.0, 34.0]);
        assert_eq!(a.neg_mul_add(b, b).to_array(), [0.0, -6.0, -16.0, -30.0]);
        let ids = F64x4::load(&[0.0, 1.0, 2.0, 3.0]);
        assert_eq!(
            a.zero_where_equal(ids, F64x4::splat(2.0)).to_array(),
            [1.0, 4.0, 0.0, 16.0]
        );
        assert_eq!(a.sum(), 30.0);
        assert_eq!(
            a.zero_unless_less(a, F64x4::splat(5.0)).to_array(),
            [1.0, 4.0, 0.0, 0.0]
        );
        assert_eq!(a.min(F64x4::splat(5.0)).to_array(), [1.0, 4.0, 5.0, 5.0]);
        let r = F64x4::load(&[0.5, 1.5, -2.5, 2.7]).round_ties_even();
        assert_eq!(r.to_array(), [0.0, 2.0, -2.0, 3.0]);
        let mut out = [0.0; 5];
        a.store(&mut out[1..]);
        assert_eq!(out, [0.0, 1.0, 4.0, 9.0, 16.0]);
        let five = F64x4::splat(5.0);
        assert_eq!(
            F64x4::select_less(a, five, b, a).to_array(),
            [2.0, 2.0, 9.0, 16.0]
        );
        // equal lanes and NaN lanes are not "less": `otherwise`
        let edge = F64x4::load(&[5.0, f64::NAN, 4.0, -0.0]);
        assert_eq!(
            F64x4::select_less(edge, F64x4::load(&[5.0, 1.0, f64::NAN, 0.0]), b, a).to_array(),
            [1.0, 4.0, 9.0, 16.0]
        );
        assert!(F64x4::any_less(a, F64x4::splat(1.5)));
        assert!(!F64x4::any_less(a, F64x4::splat(1.0)));
        assert!(!F64x4::any_less(F64x4::splat(f64::NAN), five));
        let pairs = [[1.0, -1.0], [2.0, -2.0], [3.0, -0.0], [4.0, -4.0]];
        let (x, y) = F64x4::unzip_pairs(pairs);
        assert_eq!(x.to_array(), [1.0, 2.0, 3.0, 4.0]);
        assert_eq!(
            y.to_array().map(f64::to_bits),
            [-1.0, -2.0, -0.0, -4.0f64].map(f64::to_bits)
        );
        assert_eq!(
            F64x4::zip_pairs(x, y).map(|p| p.map(f64::to_bits)),
            pairs.map(|p| p.map(f64::to_bits))
        );
    }

    /// Four lanes' inverse square root is `1 / sqrt(x)`, bit for bit.
    #[test]
    fn inverse_square_roots_of_four_lanes_are_exact() {
        for k in 0..400 {
            let x = 10f64.powf(-200.0 + f64::from(k)) * (1.0 + 0.37 * f64::from(k % 7));
            let exact = (1.0 / x.sqrt()).to_bits();
            assert_eq!(
                F64x4::splat(x).inverse_sqrt().to_array().map(f64::to_bits),
                [exact; 4]
            );
        }
    }

    #[test]
    fn the_power_of_quarters_is_two_to_the_j_quarters_times_two_to_the_n() {
        for k in -4088i32..=4092 {
            let (n, j) = (k.div_euclid(4), k.rem_euclid(4));
            // 2^(j/4) to within an ulp, and exactly the table's value
            let power = 2f64.powf(f64::from(j) / 4.0);
            assert!((QUARTER_POWERS[j as usize] - power).abs() <= power * f64::EPSILON);
            for x in [1.0, -3.25, 0.1] {
                let expected = x * QUARTER_POWERS[j as usize] * 2f64.powi(n);
                let rounded = f64::from(k) + ROUNDER;
                assert_eq!(
                    x.times_two_to_quarters(rounded).to_bits(),
                    expected.to_bits(),
                    "k {k}, x {x}"
                );
                let lanes = F64x4::splat(x).times_two_to_quarters(F64x4::splat(rounded));
                assert_eq!(
                    lanes.to_array().map(f64::to_bits),
                    [expected.to_bits(); 4],
                    "k {k}"
                );
            }
        }
    }

    #[test]
    fn the_portable_lanes_give_the_same_bits() {
        use crate::random::Rng;
        type P = portable::F64x4;
        let special = [
            0.0,
            -0.0,
            1e-7,
            -1e-7,
            1.0,
            -2.5,
            5e-324,
            1e308,
            f64::INFINITY,
            f64::NAN,
        ];
        let mut rng = Rng::new(3);
        let mut draw = |k: usize| {
            if k.is_multiple_of(3) {
                special[(rng.uniform() * special.len() as f64) as usize % special.len()]
            } else {
                (rng.uniform() - 0.5) * 10f64.powi((rng.uniform() * 20.0) as i32 - 10)
            }
        };
        let same = |fast: [f64; 4], slow: [f64; 4]| {
            (0..4).all(|l| {
                fast[l].to_bits() == slow[l].to_bits() || fast[l].is_nan() && slow[l].is_nan()
            })
        };
        for round in 0..3000 {
            let [a, b, c, d]: [[f64; 4]; 4] =
                std::array::from_fn(|_| std::array::from_fn(&mut draw));
            let (fa, fb, fc, fd) = (
                F64x4::load(&a),
                F64x4::load(&b),
                F64x4::load(&c),
                F64x4::load(&d),
            );
            let (pa, pb, pc, pd) = (P::load(&a), P::load(&b), P::load(&c), P::load(&d));
            let pairs: [(&str, [f64; 4], [f64; 4]); 9] = [
                ("+", (fa + fb).to_array(), (pa + pb).to_array()),
                ("-", (fa - fb).to_array(), (pa - pb).to_array()),
                ("*", (fa * fb).to_array(), (pa * pb).to_array()),
                ("/", (fa / fb).to_array(), (pa / pb).to_array()),
                ("sqrt", fa.sqrt().to_array(), pa.sqrt().to_array()),
                (
                    "select_less",
                    F64x4::select_less(fa, fb, fc, fd).to_array(),
                    P::select_less(pa, pb, pc, pd).to_array(),
                ),
                (
                    "zero_where_equal",
                    fa.zero_where_equal(fb, fc).to_array(),
                    pa.zero_where_equal(pb, pc).to_array(),
                ),
                (
                    "zero_unless_less",
                    fa.zero_unless_less(fb, fc).to_array(),
                    pa.zero_unless_less(pb, pc).to_array(),
                ),
                (
                    "round_ties_even",
                    fa.round_ties_even().to_array(),
                    pa.round_ties_even().to_array(),
                ),
            ];
            for (name, fast, slow) in pairs {
                assert!(
                    same(fast, slow),
                    "{name} round {round}: {a:?} {b:?}: {fast:?} against {slow:?}"
                );
            }
            assert_eq!(F64x4::any_less(fa, fb), P::any_less(pa, pb), "{a:?} {b:?}");
            assert!(same((-fa).to_array(), (-pa).to_array()), "neg {a:?}");
            // k = 4n + j over the whole exponent range, in the low bits of k + ROUNDER
            let k: [f64; 4] = std::array::from_fn(|l| ((b[l].to_bits() % 8181) as f64) - 4088.0);
            let rounded = k.map(|k| k + ROUNDER);
            let (fast, slow) = (
                fa.times_two_to_quarters(F64x4::load(&rounded)),
                pa.times_two_to_quarters(P::load(&rounded)),
            );
            assert!(same(fast.to_array(), slow.to_array()), "{a:?} {k:?}");
            let split = |v: [f64; 4]| [[v[0], v[1]], [v[2], v[3]], [c[0], c[1]], [c[2], c[3]]];
            let (fx, fy) = F64x4::unzip_pairs(split(a));
            let (px, py) = P::unzip_pairs(split(a));
            assert!(same(fx.to_array(), px.to_array()) && same(fy.to_array(), py.to_array()));
            let (fz, pz) = (F64x4::zip_pairs(fa, fb), P::zip_pairs(pa, pb));
            assert!((0..4).all(|l| same(
                [fz[l][0], fz[l][1], 0.0, 0.0],
                [pz[l][0], pz[l][1], 0.0, 0.0]
            )));
        }
    }
}
