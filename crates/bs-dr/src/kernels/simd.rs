//! Four f64 lanes, one element per lane: the small vector vocabulary the block kernels are
//! written in, with runtime dispatch between AVX2/FMA (through `pulp`'s safe `V3` token) and
//! a portable fallback.
//!
//! A kernel is a [`BlockOp`]: code generic over [`Lanes`], run by [`dispatch`]. On x86-64
//! with AVX2 and FMA the op is monomorphised for [`Avx`] and executed inside
//! `pulp::x86::V3::vectorize`, so everything it inlines is compiled with those features;
//! elsewhere it runs on [`Portable`] (`[f64; 4]`, separate multiply and add). Every helper
//! here and every kernel body must be `#[inline(always)]`, or the target features are lost
//! at the call boundary; for the same reason lane operations are not put in closures or
//! `array::map`/`from_fn` (measured: an un-inlined closure turned every `_mm256_mul_pd`
//! into a call and made the kernel 3× slower).
//!
//! Results of the two paths differ by rounding only (fused multiply-add), and one process
//! always takes the same path, so forces stay bit-identical for any thread count.

/// A way of computing on four f64 lanes at once.
pub(crate) trait Lanes: Copy {
    /// Four f64 lanes.
    type V: Copy;
    /// All lanes `x`.
    fn splat(self, x: f64) -> Self::V;
    /// Lanes from an array (lane `l` = `a[l]`).
    fn load(self, a: [f64; 4]) -> Self::V;
    /// Lanes to an array.
    fn store(self, v: Self::V) -> [f64; 4];
    /// Lanes from four f32 (converted exactly to f64).
    fn load_f32(self, a: [f32; 4]) -> Self::V;
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    fn div(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a·b + c` (fused where the hardware has it).
    fn mul_add(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `a·b − c` (fused where the hardware has it).
    fn mul_sub(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `c − a·b` (fused where the hardware has it).
    fn neg_mul_add(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// Bit `l` set iff lane `l` is `> 0` and finite (`0 < x < ∞`; NaN fails).
    fn positive_finite_mask(self, v: Self::V) -> u8;
    /// Whether every lane lies in `[lo, hi]` (NaN does not).
    fn all_in(self, v: Self::V, lo: f64, hi: f64) -> bool;
    /// The bit-level first guess of `x^(−1/3)` of `bs_material::inv_cbrt`,
    /// `from_bits(0x553e_f100_0000_0000 − bits(x)/3)` (within 3.5% for normal `x > 0`); the
    /// AVX2 version divides the high 32 bits only (a relative change below 1e-6 of a guess
    /// that the iterations refine to round-off anyway).
    fn inv_cbrt_guess(self, x: Self::V) -> Self::V;
    /// 4×4 transpose: lane `l` of output `k` is lane `k` of input `l`.
    fn transpose(self, r: [Self::V; 4]) -> [Self::V; 4];
    /// Transposed load of the x, y and z components of four padded nodal vectors
    /// `p[n[0]], …, p[n[3]]` (`[x, y, z, 0]` each): four full-width loads and a 4×4 transpose
    /// instead of twelve scalar gathers.
    fn gather_xyz(self, p: &[[f64; 4]], n: [u32; 4]) -> [Self::V; 3];
}

/// The magic constant of `bs_material::inv_cbrt`'s first guess.
pub(crate) const INV_CBRT_MAGIC: u64 = 0x553e_f100_0000_0000;

/// Runs `op` on the best lanes of this CPU (AVX2/FMA if present, else [`Portable`]).
#[inline]
pub(crate) fn dispatch<O: BlockOp>(op: O) -> O::Output {
    #[cfg(test)]
    if FORCE_PORTABLE.get() {
        return op.run(Portable);
    }
    #[cfg(target_arch = "x86_64")]
    if let Some(v3) = pulp::x86::V3::try_new() {
        return v3.vectorize(OnAvx(v3, op));
    }
    op.run(Portable)
}

#[cfg(test)]
thread_local! {
    /// Tests set this on a thread to run [`dispatch`] there on [`Portable`] lanes.
    pub(crate) static FORCE_PORTABLE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether the kernels run on AVX2/FMA lanes on this CPU (else on the portable lanes).
pub fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        pulp::x86::V3::is_available()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A kernel written once for any [`Lanes`]. `run` must be `#[inline(always)]`.
pub(crate) trait BlockOp {
    type Output;
    fn run<L: Lanes>(self, lanes: L) -> Self::Output;
}

#[cfg(target_arch = "x86_64")]
struct OnAvx<O>(pulp::x86::V3, O);

#[cfg(target_arch = "x86_64")]
impl<O: BlockOp> pulp::NullaryFnOnce for OnAvx<O> {
    type Output = O::Output;
    #[inline(always)]
    fn call(self) -> O::Output {
        self.1.run(Avx(self.0))
    }
}

/// The portable fallback: plain arrays, separate multiply and add.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

/// Lane-wise binary operation on arrays, without closures.
macro_rules! lanewise {
    ($a:ident $op:tt $b:ident) => {
        [$a[0] $op $b[0], $a[1] $op $b[1], $a[2] $op $b[2], $a[3] $op $b[3]]
    };
}

impl Lanes for Portable {
    type V = [f64; 4];
    #[inline(always)]
    fn splat(self, x: f64) -> [f64; 4] {
        [x; 4]
    }
    #[inline(always)]
    fn load(self, a: [f64; 4]) -> [f64; 4] {
        a
    }
    #[inline(always)]
    fn store(self, v: [f64; 4]) -> [f64; 4] {
        v
    }
    #[inline(always)]
    fn load_f32(self, a: [f32; 4]) -> [f64; 4] {
        [a[0] as f64, a[1] as f64, a[2] as f64, a[3] as f64]
    }
    #[inline(always)]
    fn add(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        lanewise!(a + b)
    }
    #[inline(always)]
    fn sub(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        lanewise!(a - b)
    }
    #[inline(always)]
    fn mul(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        lanewise!(a * b)
    }
    #[inline(always)]
    fn div(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        lanewise!(a / b)
    }
    #[inline(always)]
    fn mul_add(self, a: [f64; 4], b: [f64; 4], c: [f64; 4]) -> [f64; 4] {
        self.add(self.mul(a, b), c)
    }
    #[inline(always)]
    fn mul_sub(self, a: [f64; 4], b: [f64; 4], c: [f64; 4]) -> [f64; 4] {
        self.sub(self.mul(a, b), c)
    }
    #[inline(always)]
    fn neg_mul_add(self, a: [f64; 4], b: [f64; 4], c: [f64; 4]) -> [f64; 4] {
        self.sub(c, self.mul(a, b))
    }
    #[inline(always)]
    fn positive_finite_mask(self, v: [f64; 4]) -> u8 {
        let mut m = 0;
        for (l, &x) in v.iter().enumerate() {
            if x > 0.0 && x < f64::INFINITY {
                m |= 1 << l;
            }
        }
        m
    }
    #[inline(always)]
    fn transpose(self, r: [[f64; 4]; 4]) -> [[f64; 4]; 4] {
        [
            [r[0][0], r[1][0], r[2][0], r[3][0]],
            [r[0][1], r[1][1], r[2][1], r[3][1]],
            [r[0][2], r[1][2], r[2][2], r[3][2]],
            [r[0][3], r[1][3], r[2][3], r[3][3]],
        ]
    }
    #[inline(always)]
    fn all_in(self, v: [f64; 4], lo: f64, hi: f64) -> bool {
        v.iter().all(|x| (lo..=hi).contains(x))
    }
    #[inline(always)]
    fn inv_cbrt_guess(self, x: [f64; 4]) -> [f64; 4] {
        let g = |v: f64| f64::from_bits(INV_CBRT_MAGIC - v.to_bits() / 3);
        [g(x[0]), g(x[1]), g(x[2]), g(x[3])]
    }
    #[inline(always)]
    fn gather_xyz(self, p: &[[f64; 4]], n: [u32; 4]) -> [[f64; 4]; 3] {
        let r = [p[n[0] as usize], p[n[1] as usize], p[n[2] as usize], p[n[3] as usize]];
        [
            [r[0][0], r[1][0], r[2][0], r[3][0]],
            [r[0][1], r[1][1], r[2][1], r[3][1]],
            [r[0][2], r[1][2], r[2][2], r[3][2]],
        ]
    }
}

/// AVX2/FMA lanes (`__m256d`) behind `pulp`'s safe token.
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy)]
pub(crate) struct Avx(pulp::x86::V3);

#[cfg(target_arch = "x86_64")]
impl Lanes for Avx {
    type V = core::arch::x86_64::__m256d;
    #[inline(always)]
    fn splat(self, x: f64) -> Self::V {
        self.0.avx._mm256_set1_pd(x)
    }
    #[inline(always)]
    fn load(self, a: [f64; 4]) -> Self::V {
        pulp::cast(a)
    }
    #[inline(always)]
    fn store(self, v: Self::V) -> [f64; 4] {
        pulp::cast(v)
    }
    #[inline(always)]
    fn load_f32(self, a: [f32; 4]) -> Self::V {
        self.0.avx._mm256_cvtps_pd(pulp::cast(a))
    }
    #[inline(always)]
    fn add(self, a: Self::V, b: Self::V) -> Self::V {
        self.0.avx._mm256_add_pd(a, b)
    }
    #[inline(always)]
    fn sub(self, a: Self::V, b: Self::V) -> Self::V {
        self.0.avx._mm256_sub_pd(a, b)
    }
    #[inline(always)]
    fn mul(self, a: Self::V, b: Self::V) -> Self::V {
        self.0.avx._mm256_mul_pd(a, b)
    }
    #[inline(always)]
    fn div(self, a: Self::V, b: Self::V) -> Self::V {
        self.0.avx._mm256_div_pd(a, b)
    }
    #[inline(always)]
    fn mul_add(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V {
        self.0.fma._mm256_fmadd_pd(a, b, c)
    }
    #[inline(always)]
    fn mul_sub(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V {
        self.0.fma._mm256_fmsub_pd(a, b, c)
    }
    #[inline(always)]
    fn neg_mul_add(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V {
        self.0.fma._mm256_fnmadd_pd(a, b, c)
    }
    #[inline(always)]
    fn positive_finite_mask(self, v: Self::V) -> u8 {
        use core::arch::x86_64::{_CMP_GT_OQ, _CMP_LT_OQ};
        let avx = self.0.avx;
        let pos = avx._mm256_cmp_pd::<_CMP_GT_OQ>(v, avx._mm256_setzero_pd());
        let fin = avx._mm256_cmp_pd::<_CMP_LT_OQ>(v, avx._mm256_set1_pd(f64::INFINITY));
        avx._mm256_movemask_pd(avx._mm256_and_pd(pos, fin)) as u8
    }
    #[inline(always)]
    fn transpose(self, r: [Self::V; 4]) -> [Self::V; 4] {
        let avx = self.0.avx;
        let t0 = avx._mm256_unpacklo_pd(r[0], r[1]); // r0_0 r1_0 r0_2 r1_2
        let t1 = avx._mm256_unpackhi_pd(r[0], r[1]); // r0_1 r1_1 r0_3 r1_3
        let t2 = avx._mm256_unpacklo_pd(r[2], r[3]);
        let t3 = avx._mm256_unpackhi_pd(r[2], r[3]);
        [
            avx._mm256_permute2f128_pd::<0x20>(t0, t2),
            avx._mm256_permute2f128_pd::<0x20>(t1, t3),
            avx._mm256_permute2f128_pd::<0x31>(t0, t2),
            avx._mm256_permute2f128_pd::<0x31>(t1, t3),
        ]
    }
    #[inline(always)]
    fn all_in(self, v: Self::V, lo: f64, hi: f64) -> bool {
        use core::arch::x86_64::{_CMP_GE_OQ, _CMP_LE_OQ};
        let avx = self.0.avx;
        let ge = avx._mm256_cmp_pd::<_CMP_GE_OQ>(v, avx._mm256_set1_pd(lo));
        let le = avx._mm256_cmp_pd::<_CMP_LE_OQ>(v, avx._mm256_set1_pd(hi));
        avx._mm256_movemask_pd(avx._mm256_and_pd(ge, le)) == 0b1111
    }
    #[inline(always)]
    fn inv_cbrt_guess(self, x: Self::V) -> Self::V {
        let (avx, avx2) = (self.0.avx, self.0.avx2);
        let bits: core::arch::x86_64::__m256i = pulp::cast(x);
        // High words (sign bit clear for x > 0) → four i32 → f64, divide by 3, back.
        let hi = avx2._mm256_srli_epi64::<32>(bits);
        let idx = avx._mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        let hi = avx._mm256_castsi256_si128(avx2._mm256_permutevar8x32_epi32(hi, idx));
        let third = avx._mm256_mul_pd(avx._mm256_cvtepi32_pd(hi), avx._mm256_set1_pd(1.0 / 3.0));
        let q = avx2
            ._mm256_slli_epi64::<32>(avx2._mm256_cvtepu32_epi64(avx._mm256_cvttpd_epi32(third)));
        let magic = avx._mm256_set1_epi64x(INV_CBRT_MAGIC as i64);
        pulp::cast(avx2._mm256_sub_epi64(magic, q))
    }
    #[inline(always)]
    fn gather_xyz(self, p: &[[f64; 4]], n: [u32; 4]) -> [Self::V; 3] {
        let avx = self.0.avx;
        let r = [
            self.load(p[n[0] as usize]),
            self.load(p[n[1] as usize]),
            self.load(p[n[2] as usize]),
            self.load(p[n[3] as usize]),
        ];
        let t0 = avx._mm256_unpacklo_pd(r[0], r[1]); // x0 x1 z0 z1
        let t1 = avx._mm256_unpackhi_pd(r[0], r[1]); // y0 y1 w0 w1
        let t2 = avx._mm256_unpacklo_pd(r[2], r[3]); // x2 x3 z2 z3
        let t3 = avx._mm256_unpackhi_pd(r[2], r[3]); // y2 y3 w2 w3
        [
            avx._mm256_permute2f128_pd::<0x20>(t0, t2),
            avx._mm256_permute2f128_pd::<0x20>(t1, t3),
            avx._mm256_permute2f128_pd::<0x31>(t0, t2),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Probe;
    impl BlockOp for Probe {
        type Output = ([f64; 4], [[f64; 4]; 3], u8, [[f64; 4]; 4]);
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Self::Output {
            let a = l.load([1.0, 2.0, 3.0, 4.0]);
            let b = l.splat(0.5);
            let c = l.load([-1.0, 0.0, 1.0, 2.0]);
            let r = l.sub(l.div(l.mul_add(a, b, c), l.splat(2.0)), l.neg_mul_add(a, b, c));
            let p: Vec<[f64; 4]> =
                (0..6).map(|i| [i as f64, 10.0 + i as f64, 20.0 + i as f64, 0.0]).collect();
            let g = l.gather_xyz(&p, [5, 0, 3, 3]).map(|v| l.store(v));
            let m = l.positive_finite_mask(l.load([1.0, -1.0, f64::INFINITY, f64::NAN]));
            let r = l.add(r, l.load_f32([0.25, -1.5, 3.0e-3, 7.0]));
            let t =
                l.transpose([0.0, 4.0, 8.0, 12.0].map(|s| l.load([s, s + 1.0, s + 2.0, s + 3.0])));
            (l.store(r), g, m, t.map(|v| l.store(v)))
        }
    }

    #[test]
    fn avx_and_portable_lanes_agree() {
        let a = dispatch(Probe);
        let p = Probe.run(Portable);
        assert_eq!(a, p);
        assert_eq!(p.1[0], [5.0, 0.0, 3.0, 3.0]);
        assert_eq!(p.1[2], [25.0, 20.0, 23.0, 23.0]);
        assert_eq!(p.2, 0b0001);
        assert_eq!(p.3[1], [1.0, 5.0, 9.0, 13.0]);
    }
}
