//! Tensor helpers shared by the laws: the Voigt convention, kinematics (`C`, `J`), a
//! libm-free `x^(−1/3)`, the symmetric 3×3 inverse and the fourth-order products in Voigt
//! form.

use nalgebra::{Matrix3, SMatrix};

use crate::error::MaterialError;

/// 6×6 material tangent in Voigt notation (see the crate docs for the ordering).
pub type Tangent = SMatrix<f64, 6, 6>;

/// Voigt index pairs in the order `(11, 22, 33, 23, 13, 12)`.
pub const VOIGT: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];

/// `x^(−1/3)` for finite `x > 0`, to within a few ulp, without calling libm.
///
/// The hot stress kernels need `J^(−2/3) = (J²)^(−1/3)` once per element per step; the libm
/// `cbrt` the toolchain links was a quarter of the T4 kernel time. Exponent-division bit
/// guess (magic constant tuned for ≤ 3.5% error), then two steps of the cubically convergent
/// iteration `r ← r (1 + ε/3 + 2ε²/9)`, `ε = 1 − x r³` (3.5e-2 → 7e-6 → round-off), and one
/// Newton step to settle round-off (worst relative error measured against 40-digit decimal
/// arithmetic over 1e-20..1e20: 1.6e-16). Falls back to `powf` outside `[1e-300, 1e300]`.
#[inline]
pub fn inv_cbrt(x: f64) -> f64 {
    if !(1e-300..=1e300).contains(&x) {
        return x.powf(-1.0 / 3.0);
    }
    let mut r = f64::from_bits(0x553e_f100_0000_0000 - x.to_bits() / 3);
    for _ in 0..2 {
        let e = 1.0 - x * r * r * r;
        r *= 1.0 + e * (1.0 / 3.0 + e * (2.0 / 9.0));
    }
    let e = 1.0 - x * r * r * r;
    r + r * e * (1.0 / 3.0)
}

/// `C = FᵀF` and `J = det F`, or an error for `J ≤ 0` / non-finite `J`.
pub fn kinematics(f: &Matrix3<f64>) -> Result<(Matrix3<f64>, f64), MaterialError> {
    let j = f.determinant();
    if !(j > 0.0 && j.is_finite()) {
        return Err(MaterialError::NonPositiveJacobian { j });
    }
    Ok((f.transpose() * f, j))
}

pub(crate) fn jacobian_from_c(c: &Matrix3<f64>) -> Result<f64, MaterialError> {
    let d = c.determinant();
    if !(d > 0.0 && d.is_finite()) {
        return Err(MaterialError::NonPositiveJacobian { j: d.abs().sqrt().copysign(d) });
    }
    Ok(d.sqrt())
}

/// Inverse of a symmetric 3×3 matrix with known determinant (cofactor formula).
#[inline]
pub(crate) fn sym_inverse(c: &Matrix3<f64>, det: f64) -> Matrix3<f64> {
    let inv = 1.0 / det;
    let a00 = (c[(1, 1)] * c[(2, 2)] - c[(1, 2)] * c[(2, 1)]) * inv;
    let a01 = (c[(0, 2)] * c[(2, 1)] - c[(0, 1)] * c[(2, 2)]) * inv;
    let a02 = (c[(0, 1)] * c[(1, 2)] - c[(0, 2)] * c[(1, 1)]) * inv;
    let a11 = (c[(0, 0)] * c[(2, 2)] - c[(0, 2)] * c[(2, 0)]) * inv;
    let a12 = (c[(0, 2)] * c[(1, 0)] - c[(0, 0)] * c[(1, 2)]) * inv;
    let a22 = (c[(0, 0)] * c[(1, 1)] - c[(0, 1)] * c[(1, 0)]) * inv;
    Matrix3::new(a00, a01, a02, a01, a11, a12, a02, a12, a22)
}

/// Voigt tangent of `A ⊙ B` style products: `out += s · (a ⊗ b)` in Voigt form, where `a`
/// and `b` are symmetric tensors (outer product of their Voigt vectors, no shear factor).
#[inline]
pub(crate) fn add_outer(d: &mut Tangent, s: f64, a: &Matrix3<f64>, b: &Matrix3<f64>) {
    for (r, &(i, j)) in VOIGT.iter().enumerate() {
        for (q, &(k, l)) in VOIGT.iter().enumerate() {
            d[(r, q)] += s * a[(i, j)] * b[(k, l)];
        }
    }
}

/// Voigt form of the fourth-order tensor `s · ∂(A⁻¹)/∂A`-type term
/// `−s · ½ (A_ik A_jl + A_il A_jk)` for symmetric `A` (as it acts on engineering strain).
#[inline]
pub(crate) fn add_sym_product(d: &mut Tangent, s: f64, a: &Matrix3<f64>) {
    for (r, &(i, j)) in VOIGT.iter().enumerate() {
        for (q, &(k, l)) in VOIGT.iter().enumerate() {
            d[(r, q)] += s * 0.5 * (a[(i, k)] * a[(j, l)] + a[(i, l)] * a[(j, k)]);
        }
    }
}
