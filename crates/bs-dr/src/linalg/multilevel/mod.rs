//! A multilevel preconditioner for the stiffness: smoothed aggregation with the six
//! rigid-body modes as near null space, Chebyshev smoothing on every level, the coarsest
//! level factorised (faer's sparse Cholesky).
//!
//! * **Aggregates** ([`tentative`]): the mesh's nodes in each cell of a regular grid of
//!   spacing `H` ([`MultilevelParams::aggregate_size`] mean edge lengths); every coarse
//!   level's nodes (the aggregates' centroids) again on a grid [`MultilevelParams::coarsening`]
//!   times coarser. The tentative prolongator holds, per aggregate, the near null space
//!   restricted to its points, orthonormalised: on the mesh the six rigid-body modes, below
//!   the `R` factors of the level above (Vaněk, Mandel & Brezina, smoothed aggregation,
//!   1996).
//! * **Smoothing** of the prolongators: `P = (I − ω D⁻¹ A) T` with `D` the diagonal blocks
//!   (3 × 3 on the mesh, 6 × 6 below) and `ω = 4 / (3 λ_max(D⁻¹A))`; every coarse operator
//!   is the Galerkin product `Pᵀ A P` ([`products`], [`levels`]).
//! * **Storage** ([`blocks`]): 3 × 6 and 6 × 6 blocks in compressed rows, one index per
//!   block; the mesh's operator fused in single precision for the smoother ([`operator`]),
//!   the coarse operators and prolongators read in single precision by the cycle inside the
//!   double-precision GMRES.
//! * **Cycle** ([`cycle`]): a V-cycle with Chebyshev smoothing of degree `k` on `D⁻¹A` over
//!   `[λ_max/10, λ_max]` before and after each coarse correction, the coarsest level solved
//!   exactly: a symmetric positive-definite preconditioner. Two levels
//!   ([`MultilevelParams::max_levels`] 2) is the two-level method.
//! * **Constraints**: every vector lives in the subspace left by the constraints of each node
//!   (prescribed components, and the normal directions of nodes in contact), applied as the
//!   nodal orthogonal projector `Π`. The cycle runs on `Π K Π` with the block-diagonal
//!   inverse of the projected blocks; the coarse levels are the ones of the fixed
//!   components, or, when the setup kept the operator for them (every scene solve), the
//!   Galerkin levels of `(Π P)ᵀ K (Π P)` for a solve's contact set
//!   (`Multilevel::constrain_coarse`), on the setup's patterns and symbolic factor.
//! * **Following the state** ([`rebuild`]): the numbers of every level made again for the
//!   stiffness on the current configuration, the prolongators and patterns kept.
//!
//! Files: [`params`] (parameters, errors), [`projector`] (the nodal projector),
//! [`constraints`] (a solve's constraints as the cycle sees them), [`blocks`] (block-sparse
//! matrices and patterns), [`tentative`] (aggregates and the tentative prolongator),
//! [`products`] (the products on fixed patterns), [`operator`] (the mesh's operator fused in
//! single precision), [`levels`] (the coarse levels), [`setup`] (building the
//! preconditioner), [`rebuild`] (its numbers for another operator), [`cycle`] (applying it),
//! [`split`] (the mixed form of nearly incompressible T4ANP).

pub mod blocks;
pub mod constraints;
mod contact;
mod correction;
pub mod cycle;
pub mod levels;
pub(crate) mod operator;
pub mod params;
pub mod products;
pub mod projector;
pub mod rebuild;
pub mod setup;
pub mod split;
pub mod tentative;

pub use constraints::Constraints;
pub use cycle::{MultilevelBatchScratch, MultilevelScratch};
pub use params::{MultilevelError, MultilevelParams};
pub use projector::Projector;
pub use setup::Multilevel;
pub use split::{Moved, SplitScratch, VolumetricSplit};

#[cfg(test)]
mod tests;
