//! Masses and time steps of a model: the physical lumped masses and critical time steps, and
//! Dynamic Relaxation's fictitious masses, all from each element's volume, density and
//! stiffness bound, shared equally by its nodes.

use bs_mesh::{Point3, Vector3};
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::element::bound::BoundModuli;
use crate::element::{ElementView, Hex, Tet};
use crate::model::Model;

impl Model {
    /// Physical critical time step of every element (mesh element order):
    /// `Δt_e = 2/ω_e`, `ω_e² = n λ_max(K_e) / (ρ V_e)` with `K_e` the small-strain stiffness
    /// (and hourglass stiffness for H8) and the element mass `ρ V_e` lumped equally on its
    /// `n` nodes. `λ_max(K_e)` scales with the P-wave modulus `λ + 2μ`, so this is
    /// `Δt_e = L_e / c` with `c = sqrt((λ+2μ)/ρ)` the dilatational wave speed and `L_e` a
    /// length computed from the shape-function derivatives (Flanagan & Belytschko's bound
    /// made exact for the element). It bounds the global stable step from below.
    pub fn critical_time_steps(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.element_count()];
        for (e, v) in self.elements.iter() {
            let m = self.elements.solids[v.mat].density * v.vol;
            out[e] = 2.0 * (m / (v.len() as f64 * self.stiffness_bound[e])).sqrt();
        }
        out
    }

    /// Smallest physical critical time step and the element index that sets it.
    pub fn critical_time_step(&self) -> (f64, usize) {
        let steps = self.critical_time_steps();
        let mut best = (f64::INFINITY, 0);
        for (e, &s) in steps.iter().enumerate() {
            if s < best.0 {
                best = (s, e);
            }
        }
        best
    }

    /// Physical lumped nodal masses: each element's `ρ V` shared equally by its nodes.
    pub fn lumped_masses_into(&self, masses: &mut [f64]) {
        masses.iter_mut().for_each(|m| *m = 0.0);
        for (_, v) in self.elements.iter() {
            let me = self.elements.solids[v.mat].density * v.vol / v.len() as f64;
            for &n in v.nodes {
                masses[n as usize] += me;
            }
        }
    }

    /// Fictitious lumped nodal masses for Dynamic Relaxation with unit time step `h = 1`:
    /// element `e` gets mass `m_e = n λ_max(K_e) / (4 f²)`, shared equally by its `n` nodes,
    /// so that its own critical step `2/ω_e` is `h/f`: the step is the fraction `f` of the
    /// element's critical step. `step_fraction = f < 1` keeps every element below its
    /// critical step; `f = 1.5` is 1.5× critical.
    pub fn dr_masses_into(&self, step_fraction: f64, masses: &mut [f64]) {
        self.masses_from_bounds(step_fraction, &self.stiffness_bound, masses);
    }

    /// The masses of [`dr_masses_into`](Self::dr_masses_into) from the element bounds `bound`.
    fn masses_from_bounds(&self, step_fraction: f64, bound: &[f64], masses: &mut [f64]) {
        masses.iter_mut().for_each(|m| *m = 0.0);
        let f2 = step_fraction * step_fraction;
        for (e, v) in self.elements.iter() {
            let n = v.len() as f64;
            let me = n * bound[e] / (4.0 * f2);
            for &a in v.nodes {
                masses[a as usize] += me / n;
            }
        }
    }

    /// [`dr_masses_into`](Self::dr_masses_into) for a run that starts from the displacements
    /// `u` instead of the reference state: each element's bound is the larger of its
    /// reference one and the one of its shape at `X + u` (same moduli). A start state with
    /// elements flattened under a deep push (the continuation's last converged level) has
    /// critical steps far below the reference ones, and masses from the reference shapes
    /// make the explicit iteration unstable at once. An element inverted or flat at `X + u`
    /// keeps its reference bound (the forces will name it).
    pub fn dr_masses_at_into(&self, step_fraction: f64, u: &[Vector3<f64>], masses: &mut [f64]) {
        if u.iter().all(|d| *d == Vector3::zeros()) {
            return self.dr_masses_into(step_fraction, masses);
        }
        let bound = self.deformed_stiffness_bounds(u);
        self.masses_from_bounds(step_fraction, &bound, masses);
    }

    /// Each element's stiffness bound, the larger of its reference one and the one of its
    /// shape at `X + u` (mesh element order).
    pub(crate) fn deformed_stiffness_bounds(&self, u: &[Vector3<f64>]) -> Vec<f64> {
        let moduli = BoundModuli::of(&self.elements.solids);
        let reference = &self.reference;
        let (tets, tet_elem) = (&self.elements.tets, &self.elements.tet_elem);
        let tet_bounds: Vec<f64> = tets
            .par_iter()
            .map(|t| {
                let x = corners_at(reference, u, &t.nodes);
                Tet::new(t.nodes, t.mat, &x)
                    .map_or(0.0, |m| m.stiffness_bound(&moduli[t.mat as usize]))
            })
            .collect();
        let (hexes, hex_elem) = (&self.elements.hexes, &self.elements.hex_elem);
        let kappa_hg = self.options.hourglass;
        let solids = &self.elements.solids;
        let hex_bounds: Vec<f64> = hexes
            .par_iter()
            .map(|h| {
                let x = corners_at(reference, u, &h.nodes);
                let el = solids[h.mat as usize].material.elastic();
                Hex::new(h.nodes, h.mat, &x, &el, kappa_hg)
                    .map_or(0.0, |m| m.stiffness_bound(&moduli[h.mat as usize]))
            })
            .collect();
        let mut bound = self.stiffness_bound.clone();
        for (&e, b) in tet_elem.iter().zip(tet_bounds).chain(hex_elem.iter().zip(hex_bounds)) {
            bound[e as usize] = bound[e as usize].max(b);
        }
        bound
    }

    /// The masses of [`dr_masses_into`](Self::dr_masses_into) with each hexahedron's bound
    /// scaled by how much stiffer its shape at `X + u` is,
    /// `max(1, J λ_max(F⁻ᵀ S F⁻¹) / λ_max(S))` with `S = Σ_a g_a g_aᵀ` of the reference
    /// gradients: the ratio of `V λ_max(Σ_a g_a g_aᵀ)` at the current and the reference shape,
    /// which the element's largest eigenvalue follows as it flattens (`1/h²` for a
    /// thickness `h`; 1 for a rotation). A few hundred flops per element, for refreshing
    /// the masses during a run (Dynamic Relaxation does); an
    /// inverted element keeps its reference bound.
    ///
    /// Tetrahedra keep their reference bounds. A T4ANP tet's volume is resisted through the
    /// nodal averages, not by its own bulk stiffness, so its own shape overstates how stiff
    /// it grows as it flattens, and the heavier nodes lag behind the load: scaling the tets
    /// too made DR invert elements of an indented block (24 mm) and of a block at
    /// ν = 0.4999 that it carries with the reference masses (docs/decisions.md).
    pub fn dr_masses_stiffened_into(
        &self,
        step_fraction: f64,
        u: &[Vector3<f64>],
        masses: &mut [f64],
    ) {
        let mut bound = self.stiffness_bound.clone();
        let (hexes, hex_elem) = (&self.elements.hexes, &self.elements.hex_elem);
        let scaled: Vec<f64> =
            hexes.par_iter().with_min_len(256).map(|h| shape_stiffening(&h.view(), u)).collect();
        for (&e, r) in hex_elem.iter().zip(scaled) {
            bound[e as usize] *= r;
        }
        self.masses_from_bounds(step_fraction, &bound, masses);
    }

    /// The smallest element length `min_e V_e^(1/3)` (reference volumes; infinite without
    /// elements).
    pub fn smallest_element_length(&self) -> f64 {
        self.elements.iter().map(|(_, v)| v.vol.cbrt()).fold(f64::INFINITY, f64::min)
    }

    /// Total reference volume and volume-weighted sum of the small-strain shear moduli.
    pub(crate) fn volume_and_shear(&self) -> (f64, f64) {
        let mut v = 0.0;
        let mut mu = 0.0;
        for (_, e) in self.elements.iter() {
            v += e.vol;
            mu += e.vol * self.elements.solids[e.mat].material.elastic().mu;
        }
        (v, mu)
    }
}

/// `max(1, J λ_max(F⁻ᵀ S F⁻¹) / λ_max(S))` of an element at `u` (1 if inverted or
/// degenerate), `S = Σ_a g_a g_aᵀ` of its reference gradients.
fn shape_stiffening(v: &ElementView<'_>, u: &[Vector3<f64>]) -> f64 {
    let f = v.deformation_gradient(u);
    let j = f.determinant();
    let Some(f_inv) = f.try_inverse().filter(|_| j > 0.0) else { return 1.0 };
    let mut s = Matrix3::zeros();
    for g in v.g {
        let g = Vector3::from(*g);
        s += g * g.transpose();
    }
    let current = f_inv.transpose() * s * f_inv;
    let ratio = j * largest_eigenvalue(&current) / largest_eigenvalue(&s);
    if ratio.is_finite() { ratio.max(1.0) } else { 1.0 }
}

/// The largest eigenvalue of a symmetric 3×3 matrix, in closed form (the trigonometric
/// solution of the characteristic cubic, Smith 1961).
fn largest_eigenvalue(a: &Matrix3<f64>) -> f64 {
    let q = a.trace() / 3.0;
    let off = a[(0, 1)].powi(2) + a[(0, 2)].powi(2) + a[(1, 2)].powi(2);
    let diag = (a[(0, 0)] - q).powi(2) + (a[(1, 1)] - q).powi(2) + (a[(2, 2)] - q).powi(2);
    let p = ((diag + 2.0 * off) / 6.0).sqrt();
    if p <= f64::EPSILON * q.abs() {
        return q;
    }
    let b = (a - Matrix3::from_diagonal_element(q)) / p;
    let phi = (0.5 * b.determinant()).clamp(-1.0, 1.0).acos() / 3.0;
    q + 2.0 * p * phi.cos()
}

/// The corners of an element at `X + u`.
fn corners_at<const N: usize>(
    reference: &[Point3<f64>],
    u: &[Vector3<f64>],
    nodes: &[u32; N],
) -> [Point3<f64>; N] {
    nodes.map(|a| reference[a as usize] + u[a as usize])
}

#[cfg(test)]
mod tests {
    use bs_material::Material;

    use bs_mesh::Vector3;

    use crate::tests::{distorted_mesh, model};
    use crate::{Model, ModelOptions, Solid};

    /// Physical critical time step of a unit right tet (lumped mass ρV/4 per node) checked
    /// against an independent dense eigen-solve of M⁻¹K for the 12×12 small-strain stiffness
    /// assembled here from B and D.
    #[test]
    fn critical_time_step_of_a_tet_matches_dense_eigenvalue() {
        let mesh = crate::tests::unit_tet();
        let material = Material::neo_hookean(3000.0, 0.3).unwrap();
        let m = Model::uniform(&mesh, Solid { material, density: 1000.0 }, ModelOptions::default())
            .unwrap();
        let (dt, e) = m.critical_time_step();
        assert_eq!(e, 0);
        // Dense K = V Bᵀ D B with gradients of the unit tet.
        let g = [[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let d = material.elastic().small_strain_tangent();
        let mut b = nalgebra::SMatrix::<f64, 6, 12>::zeros();
        for a in 0..4 {
            let [x, y, z] = g[a];
            let c = 3 * a;
            b[(0, c)] = x;
            b[(1, c + 1)] = y;
            b[(2, c + 2)] = z;
            b[(3, c + 1)] = z;
            b[(3, c + 2)] = y;
            b[(4, c)] = z;
            b[(4, c + 2)] = x;
            b[(5, c)] = y;
            b[(5, c + 1)] = x;
        }
        let vol = 1.0 / 6.0;
        let k = b.transpose() * d * b * vol;
        let lmax = nalgebra::SymmetricEigen::new(k).eigenvalues.max();
        let omega = (lmax / (1000.0 * vol / 4.0)).sqrt();
        assert!((dt - 2.0 / omega).abs() <= 1e-10 * dt, "{dt} vs {}", 2.0 / omega);
    }

    /// Physical lumped masses add up to ρ × total volume (hex volume from bs-mesh, tets by the
    /// triple product).
    #[test]
    fn lumped_masses_sum_to_total_mass() {
        let mesh = distorted_mesh();
        let m = model();
        let mut masses = vec![0.0; m.node_count()];
        m.lumped_masses_into(&mut masses);
        let vol: f64 = (0..3).map(|e| mesh.element_volume(e)).sum();
        let total: f64 = masses.iter().sum();
        assert!((total - 1000.0 * vol).abs() <= 1e-12 * total);
        // Node 8 belongs to the two tets only: a quarter of each.
        let t = mesh.element_volume(1) + mesh.element_volume(2);
        assert!((masses[8] - 1000.0 * t / 4.0).abs() <= 1e-12 * masses[8]);
    }

    /// Masses for a start from a deformed state: each tet's bound is the larger of its
    /// reference one and the one of the same mesh built with the deformed nodes as its
    /// reference (an independent model); from zero displacements, the reference masses.
    #[test]
    fn dr_masses_at_a_deformed_state_take_each_elements_stiffer_shape() {
        for tets in [true, false] {
            let solid =
                Solid { material: Material::neo_hookean(3000.0, 0.45).unwrap(), density: 1.0 };
            let mesh = bs_mesh::structured::box_mesh(2, 1.0, tets);
            let m = Model::uniform(&mesh, solid, ModelOptions::default()).unwrap();
            let n = m.node_count();
            let (mut base, mut at) = (vec![0.0; n], vec![0.0; n]);
            m.dr_masses_into(0.8, &mut base);
            m.dr_masses_at_into(0.8, &vec![Vector3::zeros(); n], &mut at);
            assert_eq!(base, at);
            // The top pushed down by 0.45 with a strain growing to 90 % there: the upper tets flatten.
            let u: Vec<Vector3<f64>> =
                mesh.nodes.iter().map(|p| Vector3::new(0.0, 0.0, -0.45 * p.z * p.z)).collect();
            m.dr_masses_at_into(0.8, &u, &mut at);
            let mut moved = mesh.clone();
            moved.nodes.iter_mut().zip(&u).for_each(|(p, d)| *p += d);
            let md = Model::uniform(&moved, solid, ModelOptions::default()).unwrap();
            let mut expected = vec![0.0; n];
            for (e, v) in m.elements.iter() {
                let b = m.stiffness_bound[e].max(md.stiffness_bound[e]);
                for &a in v.nodes {
                    expected[a as usize] += b / (4.0 * 0.64);
                }
            }
            for (a, (x, y)) in at.iter().zip(&expected).enumerate() {
                assert!((x - y).abs() <= 1e-12 * y, "node {a}: {x} vs {y}");
            }
            let most = at.iter().zip(&base).map(|(x, y)| x / y).fold(0.0, f64::max);
            assert!(most > 1.2, "the flat elements are stiffer (tets: {tets}): {most}");
        }
    }

    /// The closed-form largest eigenvalue against nalgebra's iterative one, on random
    /// symmetric matrices and on the degenerate cases (a multiple of the identity, a double
    /// eigenvalue, a singular matrix).
    #[test]
    fn largest_eigenvalue_matches_the_iterative_one() {
        use nalgebra::Matrix3;
        let mut rng = bs_mesh::rng::SplitMix64::new(11);
        let mut cases: Vec<Matrix3<f64>> = (0..200)
            .map(|_| {
                let a = Matrix3::from_fn(|_, _| rng.uniform() * 2.0 - 1.0);
                a + a.transpose()
            })
            .collect();
        cases.push(Matrix3::identity() * 3.0);
        cases.push(Matrix3::from_diagonal(&nalgebra::Vector3::new(2.0, 2.0, -1.0)));
        cases.push(Matrix3::from_diagonal(&nalgebra::Vector3::new(0.0, 0.0, 5.0)));
        for a in cases {
            let want = a.symmetric_eigenvalues().max();
            let got = super::largest_eigenvalue(&a);
            assert!((got - want).abs() <= 1e-12 * a.norm().max(1.0), "{a}: {got} vs {want}");
        }
    }
}
