//! A two-level preconditioner for `K₀`: smoothed aggregation on geometric aggregates with a
//! Chebyshev smoother, the coarse problem factorised once (faer's sparse Cholesky).
//!
//! * **Aggregates**: the nodes in each cell of a regular grid of spacing `H`
//!   ([`TwoLevelParams::aggregate_size`] mean edge lengths). The tentative prolongator holds,
//!   per aggregate, the six rigid-body modes restricted to its nodes (the near null space of
//!   elasticity), orthonormalised (Vaněk, Mandel & Brezina, smoothed aggregation, 1996).
//! * **Smoothing**: `P = (I − ω D⁻¹ K₀) P_tent` with `D` the 3×3 nodal diagonal blocks and
//!   `ω = 4 / (3 λ_max(D⁻¹K₀))`; the coarse operator is the Galerkin product `Pᵀ K₀ P`.
//! * **Cycle**: Chebyshev smoothing of degree `k` on `D⁻¹K₀` over `[λ_max/10, λ_max]`, coarse
//!   correction, Chebyshev again: a symmetric positive-definite preconditioner.
//! * **Constraints**: every vector lives in the subspace left by the constraints of each node
//!   (prescribed components, and the normal directions of nodes in contact), applied as the
//!   nodal orthogonal projector `Π`. The cycle runs on `Π K₀ Π` with the block-diagonal
//!   inverse of the projected blocks; the coarse problem is the one of the fixed components,
//!   projected on both sides, or, when the setup kept `K₀` for it (live sessions), the
//!   Galerkin one of `Π K₀ Π` for a solve's contact set (`TwoLevel::constrain_coarse`),
//!   the setup's corrected on the held nodes' rows and factorised on its symbolic factor.
//!
//! Everything here depends only on the mesh, the materials and the fixed components: it is
//! computed once, before the loads are known.
//!
//! Files: [`params`] (parameters, errors), [`projector`] (the nodal projector),
//! [`constraints`] (a solve's constraints as the cycle sees them), [`rows`]
//! (nodal sparse rows and their products), [`operator`] (`K₀` fused in single precision for
//! the smoother), [`coarse`] (aggregates, Galerkin factor), [`correction`] (the Galerkin
//! factor of a contact set as a correction of the setup's), [`setup`] (building the preconditioner), [`cycle`] (applying it), [`split`] (the mixed form of nearly incompressible T4ANP).

pub mod coarse;
pub mod constraints;
mod correction;
pub mod cycle;
pub(crate) mod operator;
pub mod params;
pub mod projector;
pub mod rows;
pub mod setup;
pub mod split;

pub use constraints::Constraints;
pub use cycle::TwoLevelScratch;
pub use params::{TwoLevelError, TwoLevelParams};
pub use projector::Projector;
pub use setup::TwoLevel;
pub use split::{Moved, SplitScratch, VolumetricSplit};

#[cfg(test)]
mod tests;
