//! The preconditioner following the state. The preparation builds it on `K₀`, the
//! small-strain stiffness at the reference state; a brain pressed onto the skull by its
//! weight, a push of 20 mm or a flattened hexahedral mesh is far from there, and GMRES with
//! the reference preconditioner slows down (the MNI152 brain under gravity: 160 GMRES
//! iterations for one Newton step). Before a linear solve, once the elements have deformed
//! more than [`NewtonKrylovParams::rebuild_strain`](super::NewtonKrylovParams) since the
//! preconditioner in use was built (the root mean square of `‖ΔF‖`,
//! [`Model::strain_change`]), it is rebuilt on the current configuration: the stiffness
//! moved in place ([`Model::stiffness_at_into`]) and the numbers of the hierarchy made again
//! on the setup's prolongator and patterns ([`Multilevel::rebuilt`]).

use std::time::Instant;

use bs_mesh::{Point3, Vector3};

use super::Work;
use crate::assembly::StiffnessScratch;
use crate::linalg::multilevel::{Multilevel, Projector};
use crate::linalg::nodal::NodalMatrix;
use crate::model::Model;

/// The preconditioner of a solve: the preparation's, or one rebuilt on a state of the solve.
pub(crate) struct Following<'a> {
    base: &'a Multilevel,
    rebuilt: Option<Multilevel>,
    /// The stiffness on the configuration of the last rebuild (made at the first).
    k: Option<NodalMatrix>,
    scratch: StiffnessScratch,
    positions: Vec<Point3<f64>>,
    /// The displacements the one in use was built at (zero: the reference state).
    built_at: Vec<Vector3<f64>>,
}

impl<'a> Following<'a> {
    /// The preparation's preconditioner, built at the reference state of `n` nodes.
    pub(crate) fn new(base: &'a Multilevel, n: usize) -> Self {
        Following {
            base,
            rebuilt: None,
            k: None,
            scratch: StiffnessScratch::default(),
            positions: Vec::new(),
            built_at: vec![Vector3::zeros(); n],
        }
    }

    /// The one in use.
    pub(crate) fn get(&self) -> &Multilevel {
        self.rebuilt.as_ref().unwrap_or(self.base)
    }

    /// Whether the elements have deformed more than `threshold` between the state the one in
    /// use was built at and `u`.
    pub(crate) fn stale(&self, model: &Model, u: &[Vector3<f64>], threshold: f64) -> bool {
        threshold.is_finite() && model.strain_change(&self.built_at, u) > threshold
    }

    /// Rebuilds on `model` at `X + u` (fixed components `fixed`, its coarse levels for the
    /// constraints `current` of the solve); false, the one in use kept,
    /// when it cannot be: the preparation's is split for near incompressibility, an element
    /// is inverted at `u`, or the coarse matrix is singular there.
    pub(crate) fn rebuild(
        &mut self,
        model: &Model,
        u: &[Vector3<f64>],
        fixed: &Projector,
        current: &Projector,
        work: &mut Work,
    ) -> bool {
        if self.base.split().is_some() {
            return false;
        }
        let t = Instant::now();
        let reference = model.reference();
        self.positions.clear();
        self.positions.extend(reference.iter().zip(u).map(|(p, d)| p + d));
        let base = self.base;
        let k = self.k.get_or_insert_with(|| {
            base.operator().cloned().unwrap_or_else(|| model.linear_stiffness())
        });
        let built = model.stiffness_at_into(&self.positions, k, &mut self.scratch)
            && match self.base.rebuilt(k, fixed, current) {
                Ok(tl) => {
                    self.rebuilt = Some(tl);
                    true
                }
                Err(_) => false,
            };
        // A failed attempt is not made again before the state moves on as far.
        self.built_at.copy_from_slice(u);
        work.refreshes += usize::from(built);
        work.time.preconditioner += t.elapsed();
        built
    }
}
