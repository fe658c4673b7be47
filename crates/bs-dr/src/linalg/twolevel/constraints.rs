//! The constraints of one solve as the preconditioner sees them: the nodal projector, the
//! matching block-diagonal inverses and, when one was built for them, their coarse factor.

use nalgebra::Matrix3;
use std::sync::Arc;

use super::coarse::Coarse;
use super::projector::Projector;

/// The constraints of one solve as the preconditioner sees them: the nodal projector and the
/// matching block-diagonal inverses (updated when the contact set changes).
#[derive(Debug, Clone)]
pub struct Constraints {
    /// The nodal projector `Π`.
    pub projector: Projector,
    /// Inverses of the projected diagonal blocks, `(Π_a K_aa Π_a)⁺`.
    pub(super) inv_diag: Vec<Matrix3<f64>>,
    /// The coarse factor of `Pᵀ Π K₀ Π P` for these constraints, when one was built
    /// (`TwoLevel::constrain_coarse`); otherwise the preconditioner's own, built with the
    /// fixed components only.
    pub(super) coarse: Option<Arc<Coarse>>,
    /// The nodal projectors of the last build (empty before one; kept after a failed one, so
    /// that the same constraints are not tried again).
    pub(super) coarse_for: Vec<Matrix3<f64>>,
}
