//! The decoupled Neo-Hookean law on four lanes, mirroring `bs_material::NeoHookean::pk1_fj`
//! and `bs_material::inv_cbrt` formula for formula (bs-material stays scalar and free of
//! SIMD crates; a unit test pins the two together).

use super::simd::Lanes;

/// A 3×3 matrix of lanes, row-major: `m[i][j]`.
pub(crate) type Mat<V> = [[V; 3]; 3];

/// `x^(−1/3)` lane-wise: `bs_material::inv_cbrt`'s bit guess ([`Lanes::inv_cbrt_guess`]),
/// then its two cubic steps and one Newton step. A block with a lane outside `[1e-300, 1e300]`
/// (or NaN) is evaluated by the scalar function lane by lane.
#[inline(always)]
pub(crate) fn inv_cbrt<L: Lanes>(l: L, x: L::V) -> L::V {
    if !l.all_in(x, 1e-300, 1e300) {
        let mut ys = l.store(x);
        for v in ys.iter_mut() {
            *v = bs_material::inv_cbrt(*v);
        }
        return l.load(ys);
    }
    let mut r = l.inv_cbrt_guess(x);
    let one = l.splat(1.0);
    let third = l.splat(1.0 / 3.0);
    let two_ninths = l.splat(2.0 / 9.0);
    for _ in 0..2 {
        let e = l.neg_mul_add(l.mul(l.mul(x, r), r), r, one);
        r = l.mul(r, l.mul_add(e, l.mul_add(e, two_ninths, third), one));
    }
    let e = l.neg_mul_add(l.mul(l.mul(x, r), r), r, one);
    l.mul_add(l.mul(r, e), third, r)
}

/// `a b − c d`.
#[inline(always)]
pub(crate) fn cross2<L: Lanes>(l: L, a: L::V, b: L::V, c: L::V, d: L::V) -> L::V {
    l.mul_sub(a, b, l.mul(c, d))
}

/// Cofactor matrix of `F` (`cof F = J F⁻ᵀ`), entry for entry as in bs-material.
#[inline(always)]
pub(crate) fn cofactor<L: Lanes>(l: L, f: &Mat<L::V>) -> Mat<L::V> {
    [
        [
            cross2(l, f[1][1], f[2][2], f[1][2], f[2][1]),
            cross2(l, f[1][2], f[2][0], f[1][0], f[2][2]),
            cross2(l, f[1][0], f[2][1], f[1][1], f[2][0]),
        ],
        [
            cross2(l, f[0][2], f[2][1], f[0][1], f[2][2]),
            cross2(l, f[0][0], f[2][2], f[0][2], f[2][0]),
            cross2(l, f[0][1], f[2][0], f[0][0], f[2][1]),
        ],
        [
            cross2(l, f[0][1], f[1][2], f[0][2], f[1][1]),
            cross2(l, f[0][2], f[1][0], f[0][0], f[1][2]),
            cross2(l, f[0][0], f[1][1], f[0][1], f[1][0]),
        ],
    ]
}

/// `det F` from its first row and the first row of its cofactor matrix.
#[inline(always)]
pub(crate) fn det_from_cofactor<L: Lanes>(l: L, f: &Mat<L::V>, cof: &Mat<L::V>) -> L::V {
    l.mul_add(f[0][0], cof[0][0], l.mul_add(f[0][1], cof[0][1], l.mul(f[0][2], cof[0][2])))
}

/// `det F` by the first-row expansion.
#[inline(always)]
pub(crate) fn det<L: Lanes>(l: L, f: &Mat<L::V>) -> L::V {
    l.mul_add(
        f[0][0],
        cross2(l, f[1][1], f[2][2], f[1][2], f[2][1]),
        l.mul_add(
            f[0][1],
            cross2(l, f[1][2], f[2][0], f[1][0], f[2][2]),
            l.mul(f[0][2], cross2(l, f[1][0], f[2][1], f[1][1], f[2][0])),
        ),
    )
}

/// `F:F`.
#[inline(always)]
pub(crate) fn frobenius2<L: Lanes>(l: L, f: &Mat<L::V>) -> L::V {
    // Three independent row sums, then their total (short dependency chains).
    l.add(l.add(norm2(l, &f[0]), norm2(l, &f[1])), norm2(l, &f[2]))
}

/// `r·r` of a row.
#[inline(always)]
fn norm2<L: Lanes>(l: L, r: &[L::V; 3]) -> L::V {
    l.mul_add(r[2], r[2], l.mul_add(r[1], r[1], l.mul(r[0], r[0])))
}

/// Neo-Hookean parameters broadcast to lanes.
#[derive(Clone, Copy)]
pub(crate) struct NhLanes<V> {
    pub mu: V,
    pub kappa: V,
}

/// The coefficients `(α, β)` of `V_e P = α F + β cof F` for the Neo-Hookean law, given
/// `ρ = J^(−2/3)` (from [`inv_cbrt`] of `J²`), with
/// `P(F, J) = μ J^(−2/3) F + (κ J (J − 1) − μ J^(−2/3) I₁/3) J⁻¹ cof F` (bs-material's
/// `pk1_fj`, `I₁ = F:F`), scaled by the reference volume `vol`.
///
/// With `jbar` ≠ `J` it is the T4ANP force `V r⁻² P(r F, J̄)`, `r = (J̄/J)^(1/3)`: since
/// `cof(rF) = r² cof F`, `I₁(rF) = r² I₁` and `J̄^(−2/3) r⁻¹ = J^(1/3)/J̄`,
/// `V r⁻² P(rF, J̄) = V/J̄ [μ J^(1/3) F + (κ J̄ (J̄ − 1) − μ J^(−2/3) I₁/3) cof F]`:
/// one cube root (of `J²`) instead of two, and no rescaled copy of `F`. For `J̄ = J` the
/// two formulas coincide (T4).
#[inline(always)]
pub(crate) fn pk1_coefficients<L: Lanes>(
    l: L,
    p: NhLanes<L::V>,
    j: L::V,
    jbar: L::V,
    i1: L::V,
    rho: L::V,
    vol: L::V,
) -> (L::V, L::V) {
    let mu_rho = l.mul(p.mu, rho);
    let v_over_jbar = l.div(vol, jbar);
    let alpha = l.mul(l.mul(mu_rho, j), v_over_jbar);
    let vol_term = l.mul(l.mul(p.kappa, jbar), l.sub(jbar, l.splat(1.0)));
    let beta = l.mul(l.neg_mul_add(l.mul(mu_rho, i1), l.splat(1.0 / 3.0), vol_term), v_over_jbar);
    (alpha, beta)
}

#[cfg(test)]
mod tests {
    use super::super::simd::{BlockOp, Portable, dispatch};
    use super::*;

    struct Cbrt(Vec<f64>);
    impl BlockOp for Cbrt {
        type Output = Vec<f64>;
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Vec<f64> {
            self.0
                .chunks(4)
                .flat_map(|c| l.store(inv_cbrt(l, l.load([c[0], c[1], c[2], c[3]]))))
                .collect()
        }
    }

    #[test]
    fn lane_inv_cbrt_matches_bs_material() {
        let mut xs: Vec<f64> =
            (0..4000).map(|i| 10f64.powf(-30.0 + 60.0 * i as f64 / 4000.0)).collect();
        xs.extend([0.0, 1e-310, 1e301, 1.0]); // out of range: scalar fallback
        let simd = dispatch(Cbrt(xs.clone()));
        let portable = Cbrt(xs.clone()).run(Portable);
        for ((x, a), b) in xs.iter().zip(&simd).zip(&portable) {
            let r = bs_material::inv_cbrt(*x);
            if r.is_finite() {
                assert!((a - r).abs() <= 1e-15 * r, "{x}: {a} vs {r}");
                assert!((b - r).abs() <= 1e-15 * r, "{x}: {b} vs {r}");
            } else {
                assert_eq!(a.to_bits(), r.to_bits());
            }
        }
    }
}
