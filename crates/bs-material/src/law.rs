//! The [`Hyperelastic`] trait every law implements: unchecked `*_cj` kernels, checked
//! methods provided on top of them.

use nalgebra::Matrix3;

use crate::error::MaterialError;
use crate::tensor::{Tangent, jacobian_from_c, kinematics};

/// A hyperelastic law: a stateless type with a parameter type.
///
/// Implementors provide the unchecked `*_cj` kernels; the checked methods taking `F` (or `C`)
/// are provided and return [`MaterialError::NonPositiveJacobian`] for `J ≤ 0`.
pub trait Hyperelastic {
    /// The law's parameters.
    type Params: Copy + std::fmt::Debug + Send + Sync;

    /// Strain-energy density from `C` and `J` (requires `J > 0`, `J² = det C`).
    fn energy_cj(p: &Self::Params, c: &Matrix3<f64>, j: f64) -> f64;

    /// Second Piola–Kirchhoff stress from `C` and `J` (requires `J > 0`, `J² = det C`).
    fn pk2_cj(p: &Self::Params, c: &Matrix3<f64>, j: f64) -> Matrix3<f64>;

    /// `S` and the tangent `ℂ = ∂S/∂E` from `C` and `J` (requires `J > 0`, `J² = det C`).
    fn tangent_cj(p: &Self::Params, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent);

    /// First Piola–Kirchhoff stress `P = F S` from `F` and `J = det F > 0` (unchecked). The
    /// default forms `C` and `S`; laws with a cheaper direct form override it.
    #[inline]
    fn pk1_fj(p: &Self::Params, f: &Matrix3<f64>, j: f64) -> Matrix3<f64> {
        f * Self::pk2_cj(p, &(f.transpose() * f), j)
    }

    /// Strain-energy density `W(F)`.
    fn energy(p: &Self::Params, f: &Matrix3<f64>) -> Result<f64, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(Self::energy_cj(p, &c, j))
    }

    /// Second Piola–Kirchhoff stress `S(F)`.
    fn pk2(p: &Self::Params, f: &Matrix3<f64>) -> Result<Matrix3<f64>, MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(Self::pk2_cj(p, &c, j))
    }

    /// `S(F)` and the tangent `ℂ = ∂S/∂E`.
    fn tangent(
        p: &Self::Params,
        f: &Matrix3<f64>,
    ) -> Result<(Matrix3<f64>, Tangent), MaterialError> {
        let (c, j) = kinematics(f)?;
        Ok(Self::tangent_cj(p, &c, j))
    }

    /// Strain-energy density as a function of a symmetric, positive-definite `C` alone
    /// (`J = sqrt(det C)`; orientation cannot be checked from `C`).
    fn energy_c(p: &Self::Params, c: &Matrix3<f64>) -> Result<f64, MaterialError> {
        let j = jacobian_from_c(c)?;
        Ok(Self::energy_cj(p, c, j))
    }

    /// `S` as a function of `C` alone, see [`Hyperelastic::energy_c`].
    fn pk2_c(p: &Self::Params, c: &Matrix3<f64>) -> Result<Matrix3<f64>, MaterialError> {
        let j = jacobian_from_c(c)?;
        Ok(Self::pk2_cj(p, c, j))
    }
}
