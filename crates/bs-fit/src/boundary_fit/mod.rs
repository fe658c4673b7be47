//! Landmarks fitted through the boundary the shift comes from.
//!
//! A landmark inside the brain moves because the brain was pushed or pulled at its
//! boundary (the craniotomy); pulling the landmark's own material point (a spring inside the
//! brain) would explain its motion by a point force no brain feels. So the unknown is the
//! displacement `b` of a node set, in a small basis of smooth fields on it (`basis.rs`: the
//! three translations and [`BUMPS`] Gaussian bumps along the surface normal), and the fit
//! is a regularised Gauss–Newton problem for the basis amplitudes `a` (`chord.rs`):
//!
//! `min_a Σ_i w_i |d_i − u(X_i; b(a))|² + μ |a|²`,
//!
//! `d_i` the measured displacement of landmark `i`, `u(X_i; b)` the model's displacement at
//! its material point with `b` imposed, `w_i` Tukey's biweight of `|r_i|/√3` at the robust
//! scale (≥ σ). The Jacobian `∂u(X_i)/∂a` comes from one model solve per basis field at a
//! small amplitude (the caller's), the iterations are chord steps with it, each one model
//! solve, and `μ` follows the discrepancy principle counting the fit's degrees of freedom
//! ([`discrepancy`]). The model (its elasticity, the skull contact) decides everything
//! between the boundary and the landmarks; here it is a closure, so this module knows no
//! solver and no scene (bs-scene imposes the field and solves). Why a small basis and a
//! penalty on the amplitudes: fifteen landmarks at 1 mm noise determine a handful of
//! boundary amplitudes, not one per node (docs/fit.md measures the choices).

mod basis;
mod chord;

pub use basis::{BUMPS, basis, field};
pub use chord::{
    ChordFit, ChordParams, Evaluation, Priors, chord_fit, covariance, discrepancy, step, weights,
};
