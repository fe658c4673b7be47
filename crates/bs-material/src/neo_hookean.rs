//! The decoupled compressible Neo-Hookean law.

use nalgebra::Matrix3;

use crate::elastic::Elastic;
use crate::law::Hyperelastic;
use crate::tensor::{Tangent, add_outer, add_sym_product, inv_cbrt, sym_inverse};

/// Decoupled compressible Neo-Hookean law
/// `W = μ/2 (J^(−2/3) tr C − 3) + κ/2 (J − 1)²`.
///
/// `S = μ J^(−2/3) (I − (tr C / 3) C⁻¹) + κ J (J − 1) C⁻¹`. Parameters: [`Elastic`].
#[derive(Debug, Clone, Copy, Default)]
pub struct NeoHookean;

impl Hyperelastic for NeoHookean {
    type Params = Elastic;

    fn energy_cj(p: &Elastic, c: &Matrix3<f64>, j: f64) -> f64 {
        let i1 = c.trace();
        0.5 * p.mu * (i1 * j.powf(-2.0 / 3.0) - 3.0) + 0.5 * p.kappa * (j - 1.0) * (j - 1.0)
    }

    #[inline]
    fn pk2_cj(p: &Elastic, c: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        let cinv = sym_inverse(c, j * j);
        let a = p.mu * inv_cbrt(j * j);
        let i1 = c.trace();
        let b = p.kappa * j * (j - 1.0) - a * i1 / 3.0;
        let mut s = cinv * b;
        s[(0, 0)] += a;
        s[(1, 1)] += a;
        s[(2, 2)] += a;
        s
    }

    /// `P = μ J^(−2/3) (F − (I₁/3) F⁻ᵀ) + κ J (J − 1) F⁻ᵀ` with `F⁻ᵀ = cof(F)/J`, `I₁ = F:F`:
    /// no `C`, no inverse of `C`, no product `F S`.
    #[inline]
    fn pk1_fj(p: &Elastic, f: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        let cof = Matrix3::new(
            f[(1, 1)] * f[(2, 2)] - f[(1, 2)] * f[(2, 1)],
            f[(1, 2)] * f[(2, 0)] - f[(1, 0)] * f[(2, 2)],
            f[(1, 0)] * f[(2, 1)] - f[(1, 1)] * f[(2, 0)],
            f[(0, 2)] * f[(2, 1)] - f[(0, 1)] * f[(2, 2)],
            f[(0, 0)] * f[(2, 2)] - f[(0, 2)] * f[(2, 0)],
            f[(0, 1)] * f[(2, 0)] - f[(0, 0)] * f[(2, 1)],
            f[(0, 1)] * f[(1, 2)] - f[(0, 2)] * f[(1, 1)],
            f[(0, 2)] * f[(1, 0)] - f[(0, 0)] * f[(1, 2)],
            f[(0, 0)] * f[(1, 1)] - f[(0, 1)] * f[(1, 0)],
        );
        let r = inv_cbrt(j * j); // J^(−2/3); r³ = J⁻², so 1/J = J r³ (no division)
        let a = p.mu * r;
        let i1 = f.norm_squared();
        // coefficient of F⁻ᵀ = cof/J
        let b = (p.kappa * j * (j - 1.0) - a * i1 * (1.0 / 3.0)) * (j * r * r * r);
        f * a + cof * b
    }

    fn tangent_cj(p: &Elastic, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        // S = a (I − I₁/3 C⁻¹) + g C⁻¹ with a = μ J^(−2/3), g = κ J (J−1).
        // dJ/dE = J C⁻¹, dC⁻¹/dE = −(C⁻¹ ⊙ C⁻¹) (symmetrised product, times 2 for E vs C/2),
        // dI₁/dE = 2 I, da/dE = −(2/3) a C⁻¹.
        let cinv = sym_inverse(c, j * j);
        let a = p.mu / (j * j).cbrt();
        let i1 = c.trace();
        let g = p.kappa * j * (j - 1.0);
        let dg_dj = p.kappa * (2.0 * j - 1.0);
        let id = Matrix3::identity();
        let s = (id - cinv * (i1 / 3.0)) * a + cinv * g;
        let mut d = Tangent::zeros();
        // d[a (I − I₁/3 C⁻¹)]: da ⊗ (I − I₁/3 C⁻¹) = −(2/3) a (I − I₁/3 C⁻¹) ⊗ C⁻¹
        add_outer(&mut d, -2.0 / 3.0 * a, &(id - cinv * (i1 / 3.0)), &cinv);
        // −a/3 C⁻¹ ⊗ dI₁ = −(2a/3) C⁻¹ ⊗ I
        add_outer(&mut d, -2.0 / 3.0 * a, &cinv, &id);
        // −a I₁/3 dC⁻¹ = +2 a I₁/3 (C⁻¹ ⊙ C⁻¹)
        add_sym_product(&mut d, 2.0 * a * i1 / 3.0, &cinv);
        // d[g C⁻¹] = g'(J) J C⁻¹ ⊗ C⁻¹ − 2 g (C⁻¹ ⊙ C⁻¹)
        add_outer(&mut d, dg_dj * j, &cinv, &cinv);
        add_sym_product(&mut d, -2.0 * g, &cinv);
        (s, d)
    }
}
