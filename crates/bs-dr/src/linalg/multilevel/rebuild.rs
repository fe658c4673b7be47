//! The preconditioner rebuilt on another operator of the same sparsity (the stiffness on
//! the current configuration): the prolongators, the patterns and the symbolic factor of
//! the setup are kept ([`Structure`](super::setup::Structure)), and only the numbers are
//! made again — the diagonal blocks and their projected inverses, `λ_max` (by the power
//! method on the single-precision operator), the Galerkin operators of every coarse level
//! on their fixed patterns, the coarsest factor, and the smoother's fused operator.
//!
//! The coarse spaces stay the ones smoothed with the setup's operator: every coarse
//! operator is the Galerkin operator of the new one in those spaces, so the cycle is the
//! consistent multilevel method of the new operator. Measured on the MNI152 brain under
//! gravity (`scene-gravity.toml`, rebuilt on the current configuration before every Newton
//! iteration, two levels): 80 GMRES iterations with the setup's prolongator kept, 81 with
//! the whole setup made again, 302 without rebuilds; a coarse operator of `K₀` under a
//! smoother of the new operator (or the reverse) took 394 (or 2546).

use nalgebra::Matrix3;
use rayon::prelude::*;

use super::constraints::Constraints;
use super::operator::Operator32;
use super::params::MultilevelError;
use super::projector::{Projector, projected_inverse};
use super::setup::{Multilevel, REBUILD_POWER_ITERATIONS, power_max};
use crate::linalg::nodal::NodalMatrix;

impl Multilevel {
    /// This preconditioner for `k` in place of the operator it was built with (`k` of the
    /// same sparsity: the stiffness of the same model on another configuration), with the
    /// fixed components `fixed`, its coarse levels built for the constraints `current` (a
    /// solve's, contact included); the operator is kept for the contact set's coarse levels
    /// if this one kept it. Not for a split preconditioner (the nearly incompressible mixed
    /// form keeps the setup's block: rebuilt on the current configuration it took the
    /// MNI152 push at ν = 0.499 from 17 Newton / 194 GMRES iterations to 22 / 282).
    pub fn rebuilt(
        &self,
        k: &NodalMatrix,
        fixed: &Projector,
        current: &Projector,
    ) -> Result<Multilevel, MultilevelError> {
        if self.split.is_some() {
            return Err(MultilevelError::Factor("a split preconditioner is not rebuilt".into()));
        }
        let n = self.diag.len();
        let diag: Vec<Matrix3<f64>> = (0..n).into_par_iter().map(|a| k.diagonal(a)).collect();
        let inv_diag: Vec<Matrix3<f64>> =
            (0..n).into_par_iter().map(|a| projected_inverse(&diag[a], &fixed.matrix[a])).collect();
        let op32 = Operator32::new(k);
        let mut s = op32.scratch();
        let mul = |x: &[_], y: &mut [_]| op32.apply_with(x, &mut s, y, |_, o, v| *o = v);
        let mut eigenvector = self.eigenvector.clone();
        let lambda_max =
            1.1 * power_max(mul, &inv_diag, fixed, REBUILD_POWER_ITERATIONS, &mut eigenvector);
        let levels = self.levels_under(k, fixed, current)?;
        let fixed = Constraints { projector: fixed.clone(), inv_diag, levels: None };
        Ok(Multilevel {
            diag,
            op32,
            params: self.params,
            fixed,
            lambda_max,
            eigenvector,
            structure: self.structure.clone(),
            levels,
            retained: self.retained.is_some().then(|| k.clone()),
            split: None,
        })
    }
}
