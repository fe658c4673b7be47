//! Hyperelastic constitutive laws for brain tissue.
//!
//! A law maps the deformation gradient `F` to a strain-energy density and the second
//! Piola–Kirchhoff stress (and, for implicit solvers, the tangent). Laws are stateless types
//! with a separate parameter type; `J ≤ 0` is an error value, never NaN.
//!
//! Architecture invariant: this crate knows nothing about meshes, elements, solvers or
//! contact. It depends on nalgebra alone (for 3×3 algebra).
//!
//! The laws (Neo-Hookean, St Venant–Kirchhoff, one-term Ogden) arrive with the solver issue.
