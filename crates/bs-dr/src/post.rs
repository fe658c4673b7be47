//! Post-processing of a solution: per-element volume ratio `J = det F` and von Mises stress,
//! what users colour a result by in ParaView.

use bs_mesh::Vector3;
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::model::Model;
use crate::solver::SolveError;

/// Per-element measures, in mesh element order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElementMeasures {
    /// Volume ratio `J = det F` (T4: exact; H8: of the mean deformation gradient).
    pub volume_ratio: Vec<f64>,
    /// Von Mises equivalent of the Cauchy stress `σ = F S Fᵀ / J`, in the modulus unit (Pa).
    pub von_mises: Vec<f64>,
}

/// Von Mises equivalent stress of a symmetric Cauchy stress.
pub fn von_mises(s: &Matrix3<f64>) -> f64 {
    let d = [s[(0, 0)] - s[(1, 1)], s[(1, 1)] - s[(2, 2)], s[(2, 2)] - s[(0, 0)]];
    let shear = s[(0, 1)].powi(2) + s[(1, 2)].powi(2) + s[(0, 2)].powi(2);
    (0.5 * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 3.0 * shear).sqrt()
}

impl Model {
    /// The smallest element volume ratio `J = det F` at `displacements` (each element's own
    /// deformation gradient, as [`element_measures`](Self::element_measures); 1 without
    /// elements).
    pub fn min_volume_ratio(&self, displacements: &[Vector3<f64>]) -> f64 {
        let views: Vec<_> = self.elements.iter().map(|(_, v)| v).collect();
        views
            .par_iter()
            .with_min_len(1024)
            .map(|v| v.deformation_gradient(displacements).determinant())
            .reduce(|| 1.0, f64::min)
    }

    /// How far the elements deformed between `from` and `to`: the volume-weighted root mean
    /// square over the elements of `‖F(to) − F(from)‖` (Frobenius; a rigid translation is
    /// zero, a rotation by θ about `2 sin(θ/2) √2`). Deterministic for any thread count.
    pub fn strain_change(&self, from: &[Vector3<f64>], to: &[Vector3<f64>]) -> f64 {
        let views: Vec<_> = self.elements.iter().map(|(_, v)| v).collect();
        let sums: Vec<(f64, f64)> = views
            .par_chunks(1024)
            .map(|chunk| {
                chunk.iter().fold((0.0, 0.0), |(s, v), e| {
                    let d = e.deformation_gradient(to) - e.deformation_gradient(from);
                    (s + e.vol * d.norm_squared(), v + e.vol)
                })
            })
            .collect();
        let (s, v) = sums.iter().fold((0.0, 0.0), |(a, b), (s, v)| (a + s, b + v));
        if v > 0.0 { (s / v).sqrt() } else { 0.0 }
    }

    /// The largest ratio `κ/μ` of bulk to shear modulus of the solids (0 without solids).
    pub fn max_bulk_to_shear(&self) -> f64 {
        let ratio = |s: &crate::Solid| {
            let e = s.material.elastic();
            if e.mu > 0.0 { e.kappa / e.mu } else { f64::INFINITY }
        };
        self.elements.solids.iter().map(ratio).fold(0.0, f64::max)
    }

    /// `J` and von Mises stress of every element for `displacements` (indexed like the
    /// nodes). Uses the element's own deformation gradient (for T4ANP the von Mises stress of
    /// the decoupled laws is unaffected by the nodal pressure averaging, which only changes
    /// the volumetric part). An inverted element is an error naming it.
    pub fn element_measures(
        &self,
        displacements: &[Vector3<f64>],
    ) -> Result<ElementMeasures, SolveError> {
        if displacements.len() != self.node_count() {
            return Err(SolveError::LoadMismatch {
                expected: self.node_count(),
                got: displacements.len(),
            });
        }
        let ne = self.element_count();
        let mut out = ElementMeasures { volume_ratio: vec![0.0; ne], von_mises: vec![0.0; ne] };
        // In parallel, then in element-iteration order: the first inverted element is named
        // whatever the threads.
        let measured: Vec<(usize, f64, Option<f64>)> = self
            .elements
            .par_iter()
            .map(|(e, v)| {
                let f = v.deformation_gradient(displacements);
                let j = f.determinant();
                let s = self.elements.solids[v.mat].material.pk2(&f).ok();
                (e, j, s.map(|s| von_mises(&(f * s * f.transpose() / j))))
            })
            .collect();
        for (e, j, vm) in measured {
            let Some(vm) = vm else {
                return Err(SolveError::ElementInverted {
                    step: 0,
                    element: e,
                    element_id: self.element_ids()[e],
                    jacobian: j,
                });
            };
            out.volume_ratio[e] = j;
            out.von_mises[e] = vm;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Model, ModelOptions, Solid};
    use bs_material::Material;
    use bs_mesh::{Element, Mesh, Point3};

    #[test]
    fn uniaxial_stretch_of_one_tet_matches_the_closed_form() {
        // F = diag(λ, 1, 1) on a single tet: J = λ, and for St Venant–Kirchhoff
        // S = λ_L tr(E) I + 2 μ E with E = diag((λ²−1)/2, 0, 0); σ = F S Fᵀ / J.
        let nodes = vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let mesh = Mesh::new(nodes.clone(), vec![Element::tet4([0, 1, 2, 3])]);
        let (young, nu) = (3000.0, 0.3);
        let solid =
            Solid { material: Material::st_venant_kirchhoff(young, nu).unwrap(), density: 1.0 };
        let model = Model::uniform(&mesh, solid, ModelOptions::default()).unwrap();
        let stretch = 1.1;
        let u: Vec<Vector3<f64>> =
            nodes.iter().map(|p| Vector3::new((stretch - 1.0) * p.x, 0.0, 0.0)).collect();
        let m = model.element_measures(&u).unwrap();
        let mu = young / (2.0 * (1.0 + nu));
        let lambda = young * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let e11 = 0.5 * (stretch * stretch - 1.0);
        let s11 = (lambda + 2.0 * mu) * e11;
        let s22 = lambda * e11;
        let (sig11, sig22) = (stretch * stretch * s11 / stretch, s22 / stretch);
        approx::assert_relative_eq!(m.volume_ratio[0], stretch, epsilon = 1e-14);
        approx::assert_relative_eq!(m.von_mises[0], (sig11 - sig22).abs(), epsilon = 1e-10);
    }

    #[test]
    fn von_mises_of_pure_shear_is_sqrt3_tau() {
        let mut s = Matrix3::zeros();
        s[(0, 1)] = 2.0;
        s[(1, 0)] = 2.0;
        approx::assert_relative_eq!(von_mises(&s), 2.0 * 3f64.sqrt(), epsilon = 1e-15);
    }
}
