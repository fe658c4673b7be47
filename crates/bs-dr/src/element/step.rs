//! The largest step along a direction that keeps one element's volume ratio above a
//! fraction of its current value (the Newton–Krylov line search's first trial caps every
//! step by it, so that no iterate inverts an element).
//!
//! For an element whose deformation gradient is affine in the nodal displacements (the
//! linear tetrahedron, and the mean-strain hexahedron's mean gradient `F̄`), moving the
//! displacements `u` by `α d` gives `F(α) = F + α G` with `G = Σ_a d_a ⊗ ∂N_a/∂X`, and
//!
//! ```text
//! det(F + α G) = det F + α tr(adj(F) G) + α² tr(adj(G) F) + α³ det G,
//! ```
//!
//! a cubic in `α`. The bound is the smallest `α > 0` at which `det(F + α G) = c det F` (`c`
//! the kept fraction), found exactly: the cubic is split at its turning points into monotone
//! pieces and the first piece whose end falls below the level is bisected to machine
//! precision, keeping the side above the level.

use bs_mesh::Vector3;
use nalgebra::Matrix3;

/// Coefficients `(c0, c1, c2, c3)` of `det(F + α G)`.
pub(crate) fn det_cubic(f: &Matrix3<f64>, g: &Matrix3<f64>) -> [f64; 4] {
    let cof = |m: &Matrix3<f64>| {
        Matrix3::new(
            m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)],
            m[(1, 2)] * m[(2, 0)] - m[(1, 0)] * m[(2, 2)],
            m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)],
            m[(0, 2)] * m[(2, 1)] - m[(0, 1)] * m[(2, 2)],
            m[(0, 0)] * m[(2, 2)] - m[(0, 2)] * m[(2, 0)],
            m[(0, 1)] * m[(2, 0)] - m[(0, 0)] * m[(2, 1)],
            m[(0, 1)] * m[(1, 2)] - m[(0, 2)] * m[(1, 1)],
            m[(0, 2)] * m[(1, 0)] - m[(0, 0)] * m[(1, 2)],
            m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)],
        )
    };
    let (cf, cg) = (cof(f), cof(g));
    let c0 = (0..3).map(|j| f[(0, j)] * cf[(0, j)]).sum();
    let c3 = (0..3).map(|j| g[(0, j)] * cg[(0, j)]).sum();
    [c0, cf.component_mul(g).sum(), cg.component_mul(f).sum(), c3]
}

/// The smallest `α ∈ (0, alpha_max]` with `p(α) = level`, for the cubic `p` with
/// coefficients `c` and `p(0) > level`; `alpha_max` when `p` stays above `level` there. The
/// value returned satisfies `p(α) ≥ level` (to the rounding of one evaluation).
pub fn first_crossing(c: [f64; 4], level: f64, alpha_max: f64) -> f64 {
    if stays_above(c, level, alpha_max) { alpha_max } else { search(c, level, alpha_max) }
}

/// [`first_crossing`] by the turning points of the cubic and bisection.
fn search(c: [f64; 4], level: f64, alpha_max: f64) -> f64 {
    let p = |a: f64| ((c[3] * a + c[2]) * a + c[1]) * a + c[0] - level;
    // Turning points: roots of p'(α) = c1 + 2 c2 α + 3 c3 α².
    let mut cuts = [alpha_max; 3];
    let (qa, qb, qc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    if qa != 0.0 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            // The numerically stable pair of roots.
            let s = -0.5 * (qb + qb.signum() * disc.sqrt());
            let r1 = if s != 0.0 { qc / s } else { 0.0 };
            let r2 = s / qa;
            cuts[0] = r1.min(r2);
            cuts[1] = r1.max(r2);
        }
    } else if qb != 0.0 {
        cuts[0] = -qc / qb;
    }
    let mut lo = 0.0;
    for &cut in cuts.iter().filter(|&&x| x > 0.0 && x < alpha_max).chain([&alpha_max]) {
        if cut <= lo {
            continue;
        }
        if p(cut) > 0.0 {
            lo = cut;
            continue;
        }
        // p(lo) > 0 ≥ p(cut), p monotone between: bisect, keeping the side above the level.
        let mut hi = cut;
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if p(mid) > 0.0 { lo = mid } else { hi = mid }
        }
        return lo;
    }
    alpha_max
}

/// Whether `p(α) > level` on all of `[0, alpha_max]` by the bound
/// `p(α) ≥ c0 − |c1| a − |c2| a² − |c3| a³` (`a = alpha_max`), with a margin far above the
/// rounding of either evaluation: most elements of a Newton step pass it, and skip the
/// search for turning points (which, for them, returns `alpha_max` too).
fn stays_above(c: [f64; 4], level: f64, alpha_max: f64) -> bool {
    let a = alpha_max;
    let drop = ((c[3].abs() * a + c[2].abs()) * a + c[1].abs()) * a;
    c[0] - level - drop > 1e-12 * (c[0].abs() + level.abs() + drop)
}

/// `Σ_a v_a ⊗ g_a` over an element's nodes.
pub(crate) fn gradient<const N: usize>(
    v: &[Vector3<f64>],
    nodes: &[u32; N],
    g: &[[f64; 3]; N],
) -> Matrix3<f64> {
    let mut m = Matrix3::zeros();
    for a in 0..N {
        let va = &v[nodes[a] as usize];
        for j in 0..3 {
            for i in 0..3 {
                m[(i, j)] += va[i] * g[a][j];
            }
        }
    }
    m
}

/// The coefficients of one element's `det(F + α G)` at the displacements `u` along `d`.
pub(crate) fn element_cubic<const N: usize>(
    u: &[Vector3<f64>],
    d: &[Vector3<f64>],
    nodes: &[u32; N],
    g: &[[f64; 3]; N],
) -> [f64; 4] {
    let f = Matrix3::identity() + gradient(u, nodes, g);
    det_cubic(&f, &gradient(d, nodes, g))
}

/// The bound of a volume ratio with the cubic `c`: `alpha_max` unless it would fall below
/// `fraction` of its current value `c[0]` within it; 0 when it is not positive now.
pub(crate) fn cubic_bound(c: [f64; 4], fraction: f64, alpha_max: f64) -> f64 {
    if c[0].is_nan() || c[0] <= 0.0 {
        // Already inverted (or not finite): no step keeps it valid.
        return 0.0;
    }
    first_crossing(c, fraction * c[0], alpha_max)
}

/// The bound of one element: `alpha_max` unless its volume ratio would fall below
/// `fraction` of its current value within it.
pub(crate) fn element_bound<const N: usize>(
    u: &[Vector3<f64>],
    d: &[Vector3<f64>],
    nodes: &[u32; N],
    g: &[[f64; 3]; N],
    fraction: f64,
    alpha_max: f64,
) -> f64 {
    cubic_bound(element_cubic(u, d, nodes, g), fraction, alpha_max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// det(F + αG) from the coefficients equals the determinant computed directly.
    #[test]
    fn the_cubic_is_the_determinant() {
        let f = Matrix3::new(1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.2);
        let g = Matrix3::new(-0.3, 0.1, 0.4, 0.2, -0.5, 0.1, 0.3, 0.2, -0.4);
        let c = det_cubic(&f, &g);
        for a in [0.0, 0.3, 0.7, 1.0, 2.5] {
            let direct = (f + g * a).determinant();
            let poly = ((c[3] * a + c[2]) * a + c[1]) * a + c[0];
            assert!((direct - poly).abs() < 1e-12, "{a}: {direct} vs {poly}");
        }
    }

    /// Uniaxial compression `F = diag(1 − α s, 1, 1)`: `J = 1 − α s` reaches `c` at
    /// `α = (1 − c)/s` (closed form).
    #[test]
    fn uniaxial_compression_reaches_the_fraction_in_closed_form() {
        let f = Matrix3::identity();
        let g = Matrix3::new(-2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let a = first_crossing(det_cubic(&f, &g), 0.25, 1.0);
        assert!((a - 0.375).abs() < 1e-15, "{a}");
        // A bound beyond alpha_max is alpha_max.
        assert_eq!(first_crossing(det_cubic(&f, &g), 0.25, 0.2), 0.2);
    }

    /// A cubic that dips below the level and comes back: the first crossing is found, not
    /// the last, and never a point below the level.
    #[test]
    fn the_first_crossing_of_a_non_monotone_cubic() {
        // p(α) = −(α − 0.2)(α − 0.4)(α − 3) = −α³ + 3.6 α² − 1.88 α + 0.24: positive at 0,
        // negative in (0.2, 0.4), positive again in (0.4, 3).
        let c = [0.24, -1.88, 3.6, -1.0];
        let a = first_crossing(c, 0.0, 1.0);
        assert!((a - 0.2).abs() < 1e-12, "{a}");
        let p = |x: f64| ((c[3] * x + c[2]) * x + c[1]) * x + c[0];
        assert!(p(a) >= 0.0);
    }

    /// The quick bound answers only where the search gives `alpha_max` too: random cubics
    /// around a volume ratio of one, steps from 1e-3 to 1, levels from 0.05 to 0.9.
    #[test]
    fn the_quick_bound_agrees_with_the_search() {
        let mut rng = bs_mesh::rng::SplitMix64::new(11);
        let mut quick = 0;
        for k in 0..20_000 {
            let mut r = || rng.range(-1.0, 1.0);
            let scale = [0.1, 1.0, 10.0][k % 3];
            let c = [1.0 + 0.5 * r(), scale * r(), scale * r(), scale * r()];
            let level = c[0] * [0.05, 0.5, 0.9][(k / 9) % 3];
            let alpha_max = [1e-3, 0.1, 1.0][(k / 3) % 3];
            let (a, b) = (first_crossing(c, level, alpha_max), search(c, level, alpha_max));
            assert_eq!(a.to_bits(), b.to_bits(), "{c:?} {level} {alpha_max}");
            quick += usize::from(stays_above(c, level, alpha_max));
        }
        // Both branches are exercised.
        assert!(quick > 2_000 && quick < 18_000, "{quick}");
    }

    /// Brute force: on random elements and directions, the bound keeps det F above the
    /// fraction on a fine sampling of [0, α], and is tight (a step 1e-9 longer falls below,
    /// unless the bound is alpha_max).
    #[test]
    fn the_bound_matches_a_brute_force_scan() {
        let mut rng = bs_mesh::rng::SplitMix64::new(7);
        for _ in 0..500 {
            let mut r = || rng.range(-1.0, 1.0);
            let f = Matrix3::identity() + Matrix3::from_fn(|_, _| 0.3 * r());
            let g = Matrix3::from_fn(|_, _| 2.0 * r());
            let j0 = f.determinant();
            if j0 <= 0.0 {
                continue;
            }
            let a = first_crossing(det_cubic(&f, &g), 0.3 * j0, 1.0);
            for k in 0..=2000 {
                let s = a * k as f64 / 2000.0;
                assert!((f + g * s).determinant() >= 0.3 * j0 - 1e-9, "{s} < {a}");
            }
            if a < 1.0 {
                assert!((f + g * (a + 1e-7)).determinant() < 0.3 * j0 + 1e-6);
            }
        }
    }
}
