//! The preconditioner refreshed for large deformations. It is built from `K₀`, the
//! small-strain stiffness at the reference state; when the brain is pushed far (20 mm on
//! the MNI152 demo, smallest J 0.35) the tangent drifts from `K₀` and GMRES slows down
//! (12 iterations per Newton iteration against 7 at 8 mm). A linear solve that converged
//! slowly then triggers a rebuild on the current configuration (`K₀` with the gradients and
//! volumes at `X + u`, `crate::assembly::stiffness::linear_stiffness_at`), kept for the
//! rest of its load level. Measured on the MNI152 brain pushed from 20 to 21 mm: 117 → 70
//! GMRES iterations; from 7 to 8 mm the rebuilt one is no better (54 → 59), which is why
//! it waits for a slow solve instead of running every iteration.

use std::cell::{Cell, OnceCell};
use std::time::Instant;

use bs_mesh::{Point3, Vector3};

use super::Work;
use crate::linalg::twolevel::{Projector, TwoLevel, TwoLevelParams};
use crate::model::Model;

/// Rebuilds per solve at most.
pub(crate) const MAX_REFRESHES: usize = 2;

/// A linear solve of at least this many iterations …
const MIN_ITERATIONS: usize = 8;

/// … to a relative residual of at most this (the loose solves while the contact set moves
/// are short and their rates noisy) …
const MAX_JUDGED_RTOL: f64 = 0.1;

/// … whose residual fell by less than this per iteration on average asks for a rebuild
/// (the MNI152 demo's solves reduce it by 0.74–0.81 per iteration at 8 mm, 0.84 at 20 mm).
const SLOW_RATE: f64 = 0.82;

/// The elements must have changed volume this much (smallest `J` below it) for `K₀` to
/// have drifted from the tangent: on the MNI152 brain at 12 mm (smallest J 0.71) a rebuild
/// saved 2 of 121 GMRES iterations and cost more than they did; at 16 mm (0.54) it saved 44
/// of 213, at 20 mm (0.35) 66 of 227, at 25 mm (0.14) 127 of 360.
const MAX_VOLUME_RATIO: f64 = 0.6;

/// Above this ratio of bulk to shear modulus (ν > 0.495) GMRES is slow because of the
/// volumetric stiffness, the two-level preconditioner's known limit, which a rebuild on
/// the deformed geometry does not lift: on the MNI152 brain at ν = 0.499 (κ/μ 500) the
/// rebuilds took the 8 mm push from 45 to 127 Newton iterations and from 1790 to 2291
/// GMRES iterations (the iterates there pass through element volume ratios below 0.6 that
/// the converged state, 0.86, does not have).
const MAX_BULK_TO_SHEAR: f64 = 100.0;

/// Whether a linear solve to the relative residual `rtol` in `iterations` GMRES iterations
/// was slow.
pub(crate) fn slow(rtol: f64, iterations: usize) -> bool {
    rtol <= MAX_JUDGED_RTOL
        && iterations >= MIN_ITERATIONS
        && rtol.powf(1.0 / iterations as f64) > SLOW_RATE
}

/// The preconditioners of one solve: the preparation's, then the rebuilt ones. A rebuilt
/// one serves the rest of the load level it was built in; the next level starts again from
/// the preparation's. Kept across levels, the two rebuilds of the fine ellipsoid's 40 mm
/// continuation (35 levels) served levels far more deformed than the state they were
/// built at: 38 532 GMRES iterations against 24 491 without rebuilds.
pub(crate) struct Preconditioners<'a> {
    base: &'a TwoLevel,
    rebuilt: [OnceCell<TwoLevel>; MAX_REFRESHES],
    /// Which is in use: 0 the base, `k` the `k`-th rebuilt.
    in_use: Cell<usize>,
}

impl<'a> Preconditioners<'a> {
    pub(crate) fn new(base: &'a TwoLevel) -> Self {
        Preconditioners { base, rebuilt: Default::default(), in_use: Cell::new(0) }
    }

    /// The one in use.
    pub(crate) fn current(&self) -> &TwoLevel {
        match self.in_use.get() {
            0 => self.base,
            k => self.rebuilt[k - 1].get().unwrap_or(self.base),
        }
    }

    /// Back to the preparation's (a new load level); true when another was in use.
    pub(crate) fn reset(&self) -> bool {
        self.in_use.replace(0) != 0
    }

    /// Rebuilds on `model` at `X + u` (fixed components `fixed`, the given parameters) when
    /// the elements have changed volume enough; false when they have not, when the
    /// material is nearly incompressible, when no rebuild is left, or when it could not be
    /// built (an
    /// element inverted or flat at `u`, hexahedra, a singular coarse problem: the one in
    /// use stays).
    pub(crate) fn refresh(
        &self,
        model: &Model,
        u: &[Vector3<f64>],
        fixed: &Projector,
        params: TwoLevelParams,
        work: &mut Work,
    ) -> bool {
        let Some(k) = self.rebuilt.iter().position(|c| c.get().is_none()) else { return false };
        if model.max_bulk_to_shear() > MAX_BULK_TO_SHEAR {
            return false;
        }
        let t = Instant::now();
        if model.min_volume_ratio(u) >= MAX_VOLUME_RATIO {
            work.time.preconditioner += t.elapsed();
            return false;
        }
        let x: Vec<Point3<f64>> = model.reference().iter().zip(u).map(|(p, d)| p + d).collect();
        let built = model
            .linear_stiffness_at(&x)
            .and_then(|k| TwoLevel::new(k, &x, model.mean_edge(), fixed, params).ok());
        work.time.preconditioner += t.elapsed();
        match built {
            Some(tl) => {
                work.refreshes += 1;
                let set = self.rebuilt[k].set(tl).is_ok();
                if set {
                    self.in_use.set(k + 1);
                }
                set
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slow_is_the_mean_reduction_per_iteration() {
        // 0.01 in 17 iterations: 0.763 per iteration (the 8 mm demo) is not slow.
        assert!(!slow(0.01, 17));
        // 0.01 in 25: 0.832 is.
        assert!(slow(0.01, 25));
        // 0.1 in 12: 0.825 is; in 11: 0.811 is not.
        assert!(slow(0.1, 12));
        assert!(!slow(0.1, 11));
        // Few iterations are never judged (0.1 in 7: 0.72), nor loose solves (0.5 in 9).
        assert!(!slow(0.1, 7));
        assert!(!slow(0.5, 9));
    }

    /// A 3 × 3 × 3 tet box (T4ANP, neo-Hookean) with its bottom face fixed.
    fn box_model() -> (Model, Projector) {
        use crate::{ModelOptions, Solid, TetFormulation};
        let mesh = bs_mesh::structured::box_mesh(3, 1.0, true);
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

    /// `u_z = −s z`: every element's volume ratio is `1 − s`.
    fn squeeze(model: &Model, s: f64) -> Vec<Vector3<f64>> {
        model.reference().iter().map(|p| Vector3::new(0.0, 0.0, -s * p.z)).collect()
    }

    #[test]
    fn a_rebuild_waits_for_a_large_volume_change_and_is_k0_of_the_deformed_mesh() {
        let (model, fixed) = box_model();
        let params = TwoLevelParams::default();
        let base = TwoLevel::new(
            model.linear_stiffness(),
            model.reference(),
            model.mean_edge(),
            &fixed,
            params,
        )
        .unwrap();
        let pre = Preconditioners::new(&base);
        let mut work = Work::default();
        // J = 0.7: K₀ still fits.
        assert!(!pre.refresh(&model, &squeeze(&model, 0.3), &fixed, params, &mut work));
        assert!(std::ptr::eq(pre.current(), &base));
        // J = 0.5: rebuilt, and equal to K₀ of a model meshed on the squeezed box (an
        // independent construction: other gradients, volumes and nodal vectors).
        let u = squeeze(&model, 0.5);
        assert!(pre.refresh(&model, &u, &fixed, params, &mut work));
        assert!(!std::ptr::eq(pre.current(), &base));
        assert_eq!(work.refreshes, 1);
        let mut mesh = bs_mesh::structured::box_mesh(3, 1.0, true);
        for (p, d) in mesh.nodes.iter_mut().zip(&u) {
            *p += d;
        }
        let deformed = Model::uniform(&mesh, model.elements.solids[0], model.options()).unwrap();
        let x: Vec<Point3<f64>> = model.reference().iter().zip(&u).map(|(p, d)| p + d).collect();
        let (k, expect) = (model.linear_stiffness_at(&x).unwrap(), deformed.linear_stiffness());
        let scale = expect.assembled.val.iter().fold(0.0f64, |m, b| m.max(b.amax()));
        assert_eq!(k.assembled.col, expect.assembled.col);
        for (a, b) in k.assembled.val.iter().zip(&expect.assembled.val) {
            assert!((a - b).amax() <= 1e-12 * scale);
        }
        let (kn, en) = (k.nodal.as_ref().unwrap(), expect.nodal.as_ref().unwrap());
        for (a, b) in kn.weight.iter().zip(&en.weight) {
            assert!((a - b).abs() <= 1e-12 * b.abs());
        }
        for (a, b) in kn.c_val.iter().zip(&en.c_val) {
            assert!((a - b).amax() <= 1e-9 * b.amax().max(1.0));
        }
        // The preconditioner in use is the one of that stiffness.
        for a in 0..model.node_count() {
            let d = expect.diagonal(a);
            assert!((pre.current().diagonal(a) - d).amax() <= 1e-9 * d.amax());
        }
        // Nearly incompressible (ν = 0.499, κ/μ 500): never.
        let mesh = bs_mesh::structured::box_mesh(3, 1.0, true);
        let stiff = crate::Solid {
            material: bs_material::Material::neo_hookean(3000.0, 0.499).unwrap(),
            density: 1000.0,
        };
        let incompressible = Model::uniform(&mesh, stiff, model.options()).unwrap();
        let other = Preconditioners::new(&base);
        let mut w = Work::default();
        assert!(!other.refresh(&incompressible, &u, &fixed, params, &mut w));
        assert_eq!(w.refreshes, 0);
        // A new level starts from the base again.
        assert!(pre.reset());
        assert!(std::ptr::eq(pre.current(), &base));
        assert!(!pre.reset());
        // One more, then none left.
        assert!(pre.refresh(&model, &squeeze(&model, 0.55), &fixed, params, &mut work));
        assert!(!pre.refresh(&model, &squeeze(&model, 0.6), &fixed, params, &mut work));
        assert_eq!(work.refreshes, MAX_REFRESHES);
    }
}
