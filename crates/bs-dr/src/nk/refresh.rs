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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::multilevel::MultilevelParams;
    use crate::{ModelOptions, Solid, TetFormulation};

    /// A 4 × 4 × 4 tet box (T4ANP, neo-Hookean) with its bottom face fixed.
    fn box_model() -> (Model, Projector) {
        let mesh = bs_mesh::structured::box_mesh(4, 1.0, true);
        let solid = Solid {
            material: bs_material::Material::neo_hookean(3000.0, 0.45).unwrap(),
            density: 1000.0,
        };
        let opts = ModelOptions { tet: TetFormulation::T4Anp, hourglass: 0.1 };
        let model = Model::uniform(&mesh, solid, opts).unwrap();
        let mut fixed = Projector::free(model.node_count());
        let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
        for (a, p) in model.reference().iter().enumerate() {
            if p.z == 0.0 {
                fixed.set(a, &axes);
            }
        }
        (model, fixed)
    }

    /// `u_z = −s z`: every element's `F − I` is `−s e_z ⊗ e_z`, `‖ΔF‖ = s`.
    fn squeeze(model: &Model, s: f64) -> Vec<Vector3<f64>> {
        model.reference().iter().map(|p| Vector3::new(0.0, 0.0, -s * p.z)).collect()
    }

    #[test]
    fn a_rebuild_waits_for_the_strain_and_is_built_on_the_moved_stiffness() {
        let (model, fixed) = box_model();
        let x = model.reference();
        let base = Multilevel::new(
            model.linear_stiffness(),
            x,
            model.mean_edge(),
            &fixed,
            Default::default(),
        )
        .unwrap();
        let mut pre = Following::new(&base, model.node_count());
        // The strain change of a uniform squeeze is its size.
        let u = squeeze(&model, 0.3);
        assert!((model.strain_change(&vec![Vector3::zeros(); u.len()], &u) - 0.3).abs() < 1e-12);
        assert!(!pre.stale(&model, &squeeze(&model, 0.05), 0.1));
        assert!(pre.stale(&model, &u, 0.1));
        assert!(!pre.stale(&model, &u, f64::INFINITY));
        let mut work = Work::default();
        assert!(pre.rebuild(&model, &u, &fixed, &fixed, &mut work));
        assert_eq!(work.refreshes, 1);
        assert!(!std::ptr::eq(pre.get(), &base));
        // Built at u: no longer stale there, and its diagonal is the one of K₀ of a model
        // meshed on the squeezed box (an independent construction).
        assert!(!pre.stale(&model, &u, 0.1));
        let mut mesh = bs_mesh::structured::box_mesh(4, 1.0, true);
        for (p, d) in mesh.nodes.iter_mut().zip(&u) {
            *p += d;
        }
        let moved = Model::uniform(&mesh, model.elements.solids[0], model.options()).unwrap();
        let k = moved.linear_stiffness();
        for a in 0..model.node_count() {
            let d = k.diagonal(a);
            assert!((pre.get().diagonal(a) - d).amax() <= 1e-9 * d.amax());
        }
        // A split preconditioner (ν = 0.499) is not rebuilt.
        let solid = Solid {
            material: bs_material::Material::neo_hookean(3000.0, 0.499).unwrap(),
            density: 1000.0,
        };
        let stiff =
            Model::uniform(&bs_mesh::structured::box_mesh(4, 1.0, true), solid, model.options())
                .unwrap();
        let params = MultilevelParams::default();
        let split = Multilevel::new(stiff.linear_stiffness(), x, stiff.mean_edge(), &fixed, params)
            .unwrap();
        assert!(split.split().is_some());
        let mut other = Following::new(&split, stiff.node_count());
        assert!(!other.rebuild(&stiff, &u, &fixed, &fixed, &mut work));
        assert_eq!(work.refreshes, 1);
    }
}
