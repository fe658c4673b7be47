//! Hyperelastic constitutive laws for brain tissue.
//!
//! A law maps the deformation gradient `F` to a strain-energy density `W` (per unit reference
//! volume), the second Piola–Kirchhoff stress `S = ∂W/∂E = 2 ∂W/∂C` and, for implicit
//! solvers, the material tangent `ℂ = ∂S/∂E`. Laws are stateless types implementing
//! [`Hyperelastic`] with a separate parameter type (the fenris style); [`Material`] is the
//! run-time choice of a law and its parameters, used by the element kernels.
//!
//! | law | energy density `W` |
//! |-----|--------------------|
//! | [`NeoHookean`] | `μ/2 (Ī₁ − 3) + κ/2 (J − 1)²`, `Ī₁ = J^(−2/3) tr C` (CalculiX `*HYPERELASTIC, NEO HOOKE` with `C10 = μ/2`, `D1 = 2/κ`) |
//! | [`StVenantKirchhoff`] | `λ/2 (tr E)² + μ E:E`, `E = (C − I)/2` |
//! | [`Ogden`] | `2μ/α² (λ̄₁^α + λ̄₂^α + λ̄₃^α − 3) + κ/2 (J − 1)²`, `λ̄ᵢ = J^(−1/3) λᵢ` (one term; initial shear modulus `μ` for every `α`) |
//!
//! Conventions: the tangent is a 6×6 matrix in Voigt order `(11, 22, 33, 23, 13, 12)` acting
//! on the engineering strain vector `(E₁₁, E₂₂, E₃₃, 2E₂₃, 2E₁₃, 2E₁₂)`, so `dS = ℂ dE` and
//! `ℂ` is symmetric. `J = det F ≤ 0` (an inverted material point) is a
//! [`MaterialError::NonPositiveJacobian`], never a NaN.
//!
//! The `*_cj` methods are the unchecked kernels used in hot loops: they take the right
//! Cauchy–Green tensor `C = FᵀF` and `J = det F`, and require `J > 0` and `J² = det C`.
//!
//! Every law is built from Young's modulus and Poisson's ratio `(E, ν)` or from the shear and
//! bulk moduli `(μ, κ)`, with the same checks (`E > 0`, `−1 < ν < 0.5`, `μ > 0`, `κ > 0`;
//! a [`MaterialError::InvalidParameter`] names the [`Parameter`]):
//!
//! ```
//! use bs_material::nalgebra::Matrix3;
//! use bs_material::Material;
//!
//! // Brain tissue: E = 3 kPa, ν = 0.49; the same law from its μ and κ.
//! let law = Material::neo_hookean(3000.0, 0.49).unwrap();
//! let e = law.elastic();
//! let same = Material::neo_hookean_mu_kappa(e.mu, e.kappa).unwrap();
//! let f = Matrix3::new(1.1, 0.0, 0.0, 0.0, 0.95, 0.0, 0.0, 0.0, 0.97); // deformation gradient
//! let s = law.pk2(&f).unwrap(); // second Piola–Kirchhoff stress
//! assert!((s - same.pk2(&f).unwrap()).norm() <= 1e-12 * s.norm());
//! // An inverted material point is an error value, never a NaN.
//! assert!(law.pk2(&-Matrix3::identity()).is_err());
//! assert!(Material::neo_hookean(3000.0, 0.5).is_err()); // ν must stay below 0.5
//! ```
//!
//! Files:
//! * `law.rs`: the `Hyperelastic` trait (unchecked `*_cj` kernels, checked methods on top);
//! * `tensor.rs`: the Voigt convention, `C` and `J`, `inv_cbrt`, the symmetric products;
//! * `elastic.rs`: `Elastic` (μ, κ) and `Lame` (λ, μ) with their conversions, written once;
//! * `error.rs`: `MaterialError`, `Parameter` and the parameter checks, written once;
//! * `neo_hookean.rs`, `st_venant_kirchhoff.rs`, `ogden.rs`: one file per law;
//! * `material.rs`: `Material`, the run-time choice of a law and its parameters;
//! * `closed_form.rs`: homogeneous states written out from the energies, the independent
//!   expectations of the patch tests;
//! * `tests.rs`: property tests shared by every law (test builds only).
//!
//! Architecture invariant: this crate knows nothing about meshes, elements, solvers or
//! contact. It depends on no brainshift crate, only on nalgebra (for 3×3 algebra) and
//! thiserror.

mod elastic;
mod error;
mod law;
mod material;
mod neo_hookean;
mod ogden;
mod st_venant_kirchhoff;
mod tensor;

pub mod closed_form;

/// The linear algebra of this crate's signatures (`Matrix3`), re-exported so that callers
/// need no separate dependency.
pub use nalgebra;

pub use elastic::{Elastic, Lame};
pub use error::{MaterialError, Parameter};
pub use law::Hyperelastic;
pub use material::Material;
pub use neo_hookean::NeoHookean;
pub use ogden::{Ogden, OgdenParams};
pub use st_venant_kirchhoff::StVenantKirchhoff;
pub use tensor::{Tangent, VOIGT, inv_cbrt, kinematics};

#[cfg(test)]
mod tests;
