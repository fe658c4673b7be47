//! The constraints of one solve as the preconditioner sees them: the nodal projector, the
//! matching block-diagonal inverses and, when they were built for them, their coarse levels.

use nalgebra::Matrix3;
use std::sync::Arc;

use super::levels::Levels;
use super::products::FineProducts;
use super::projector::Projector;

/// The constraints of one solve as the preconditioner sees them: the nodal projector and the
/// matching block-diagonal inverses (updated when the contact set changes).
#[derive(Debug, Clone)]
pub struct Constraints {
    /// The nodal projector `Π`.
    pub projector: Projector,
    /// Inverses of the projected diagonal blocks, `(Π_a K_aa Π_a)⁺`.
    pub(super) inv_diag: Vec<Matrix3<f64>>,
    /// The coarse levels built for these constraints (`Multilevel::constrain_coarse`);
    /// `None`: the preconditioner's own.
    pub(super) levels: Option<Built>,
}

/// Coarse levels and the constraints they were built for: the nodal projectors (a failed
/// build keeps the levels it had under the new projectors, so that the same constraints are
/// not tried again) and how many nodes they held beyond the fixed components.
#[derive(Debug, Clone)]
pub(crate) struct Built {
    pub(super) levels: Arc<Levels>,
    /// The mesh level's products under these constraints, kept by a preconditioner's own
    /// levels for the local corrections of contact sets (`None` for a correction).
    pub(super) fine: Option<Arc<FineProducts>>,
    pub(super) projector: Arc<Vec<Matrix3<f64>>>,
    pub(super) held: usize,
}
