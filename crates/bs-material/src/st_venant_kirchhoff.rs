//! The St Venant–Kirchhoff law (parameters: [`Lame`]).

use nalgebra::Matrix3;

use crate::elastic::{Elastic, Lame};
use crate::law::Hyperelastic;
use crate::tensor::Tangent;

/// St Venant–Kirchhoff law `W = λ/2 (tr E)² + μ E:E`, `S = λ tr(E) I + 2μ E`: linear
/// elasticity in the Total Lagrangian setting (the "linear elastic" ventricle region).
/// It is not polyconvex and softens in strong compression; `J ≤ 0` is still rejected.
#[derive(Debug, Clone, Copy, Default)]
pub struct StVenantKirchhoff;

impl Hyperelastic for StVenantKirchhoff {
    type Params = Lame;

    fn energy_cj(p: &Lame, c: &Matrix3<f64>, _j: f64) -> f64 {
        let e = (c - Matrix3::identity()) * 0.5;
        let tr = e.trace();
        0.5 * p.lambda * tr * tr + p.mu * e.component_mul(&e).sum()
    }

    #[inline]
    fn pk2_cj(p: &Lame, c: &Matrix3<f64>, _j: f64) -> Matrix3<f64> {
        let e = (c - Matrix3::identity()) * 0.5;
        let tr = e.trace();
        let mut s = e * (2.0 * p.mu);
        for i in 0..3 {
            s[(i, i)] += p.lambda * tr;
        }
        s
    }

    fn tangent_cj(p: &Lame, c: &Matrix3<f64>, j: f64) -> (Matrix3<f64>, Tangent) {
        let s = Self::pk2_cj(p, c, j);
        let d = Elastic::from(*p).small_strain_tangent();
        (s, d)
    }
}
