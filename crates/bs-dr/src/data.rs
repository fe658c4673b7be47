//! The measurement seam: data fitted with the model as the regulariser.
//!
//! An intra-operative measurement (a scanned surface, landmark pairs) enters a solve as an
//! energy added to the strain energy, `Π(u) + E_d(u)`, whose minimiser the solver finds.
//! The solver sees it only through [`DataTerm`]: once per Newton iteration it asks the term
//! to linearise itself at the current positions, and the term answers with [`Springs`],
//! rank-one quadratic terms
//!
//! `½ k (d · Σ_j β_j x_j − c)²`,   `x_j = X_j + u_j`,
//!
//! each a direction `d`, a target `c` along it, a stiffness `k` and the nodes and weights
//! `β_j` of a material point (a point of a boundary face for a surface measurement, of a
//! tetrahedron for a landmark). A point-to-plane term is one spring along the plane's
//! normal; a point-to-point term, three. Between two linearisations the
//! springs are fixed, so the data force `Σ k r β_j d` is linear in `u` and its Jacobian
//! the Gauss–Newton Hessian `Σ k (β ⊗ d)(β ⊗ d)ᵀ`: a Newton step of the sum is the
//! Gauss–Newton step of the data and the Newton step of the model, and an iteratively
//! reweighted robust fit is a change of `k` at the next linearisation.
//!
//! The correspondences and weights (closest points, robust statistics, rigid corrections)
//! are the term's own business, not the solver's: bs-dr knows no geometry. [`NoData`] is
//! the null term.

use bs_mesh::{Point3, Vector3};

/// One rank-one term `½ k (d · Σ_j β_j x_j − c)²` of a linearised data energy: a material
/// point (nodes and weights `β_j`) held along a unit direction `d` at `c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    /// The nodes of the material point (unused slots have weight 0).
    pub nodes: [usize; 4],
    /// Their weights `β_j` (barycentric coordinates of the material point).
    pub weights: [f64; 4],
    /// The unit direction `d` the term measures along.
    pub direction: Vector3<f64>,
    /// The target `c`: the measured position's coordinate along `d`.
    pub target: f64,
    /// The stiffness `k` (force per length).
    pub stiffness: f64,
}

impl Spring {
    /// The residual `d · Σ_j β_j x_j − c` at the displacements `u`.
    pub fn residual(&self, reference: &[Point3<f64>], u: &[Vector3<f64>]) -> f64 {
        let mut s = -self.target;
        for (&a, &b) in self.nodes.iter().zip(&self.weights) {
            if b != 0.0 {
                s += b * self.direction.dot(&(reference[a].coords + u[a]));
            }
        }
        s
    }
}

/// The springs of one linearisation, in a fixed order (forces summed in that order are
/// the same for any thread count).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Springs {
    terms: Vec<Spring>,
}

impl Springs {
    /// No springs.
    pub fn new() -> Self {
        Springs::default()
    }

    /// Removes every spring (keeps the allocation).
    pub fn clear(&mut self) {
        self.terms.clear();
    }

    /// Adds a spring.
    pub fn push(&mut self, spring: Spring) {
        self.terms.push(spring);
    }

    /// Appends the springs of `other` (measurements linearised one by one into one set).
    pub fn extend(&mut self, other: &Springs) {
        self.terms.extend_from_slice(&other.terms);
    }

    /// The springs.
    pub fn terms(&self) -> &[Spring] {
        &self.terms
    }

    /// Number of springs.
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// Adds `scale` times the gradient of the springs' energy at `u` to `f` (the force
    /// convention of [`Model::internal_forces_into`](crate::Model::internal_forces_into):
    /// the gradient of the energy, so equilibrium is `f = 0` at free components).
    pub fn add_forces_into(
        &self,
        reference: &[Point3<f64>],
        u: &[Vector3<f64>],
        scale: f64,
        f: &mut [Vector3<f64>],
    ) {
        for s in &self.terms {
            let g = s.direction * (scale * s.stiffness * s.residual(reference, u));
            for (&a, &b) in s.nodes.iter().zip(&s.weights) {
                if b != 0.0 {
                    f[a] += g * b;
                }
            }
        }
    }

    /// The springs' energy `Σ ½ k r²` at `u`.
    pub fn energy(&self, reference: &[Point3<f64>], u: &[Vector3<f64>]) -> f64 {
        self.terms
            .iter()
            .map(|s| {
                let r = s.residual(reference, u);
                0.5 * s.stiffness * r * r
            })
            .sum()
    }

    /// Adds to `out[a]` a bound on the springs' stiffness at node `a` (the row sums of the
    /// absolute Hessian, Gershgorin's bound on its largest eigenvalue): what an explicit
    /// solver's masses must carry for its step to stay stable.
    pub fn add_stiffness_bound_into(&self, out: &mut [f64]) {
        for s in &self.terms {
            let total: f64 = s.weights.iter().map(|b| b.abs()).sum();
            for (&a, &b) in s.nodes.iter().zip(&s.weights) {
                if b != 0.0 {
                    out[a] += s.stiffness * b.abs() * total;
                }
            }
        }
    }
}

/// Measurements fitted by a solve (see the module documentation).
pub trait DataTerm {
    /// Linearises the term at `positions`, the current coordinates of every node, into
    /// `springs` (replacing what it held). Called before the first iteration and once per
    /// Newton iteration (every few hundred steps by Dynamic Relaxation).
    fn linearise(&mut self, positions: &[Point3<f64>], springs: &mut Springs);

    /// Whether the term can pull at all (a solve without data skips the linearisations).
    fn is_active(&self) -> bool {
        true
    }
}

/// The null term: no data.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoData;

impl DataTerm for NoData {
    fn linearise(&mut self, _positions: &[Point3<f64>], springs: &mut Springs) {
        springs.clear();
    }

    fn is_active(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spring() -> Spring {
        along(Vector3::new(0.0, 0.6, 0.8), 1.5, 4.0)
    }

    fn along(direction: Vector3<f64>, target: f64, stiffness: f64) -> Spring {
        Spring { nodes: [0, 1, 2, 0], weights: [0.2, 0.3, 0.5, 0.0], direction, target, stiffness }
    }

    fn points() -> Vec<Point3<f64>> {
        vec![Point3::new(0.0, 0.0, 1.0), Point3::new(1.0, 0.0, 2.0), Point3::new(0.0, 1.0, 1.5)]
    }

    /// The force is the gradient of the energy: central differences of `energy` agree.
    #[test]
    fn forces_are_the_gradient_of_the_energy() {
        let mut s = Springs::new();
        s.push(spring());
        s.push(along(Vector3::x(), -0.3, 1.5));
        let x = points();
        let u = vec![
            Vector3::new(0.1, -0.2, 0.05),
            Vector3::new(0.0, 0.3, -0.1),
            Vector3::new(-0.2, 0.1, 0.2),
        ];
        let mut f = vec![Vector3::zeros(); 3];
        s.add_forces_into(&x, &u, 1.0, &mut f);
        let h = 1e-6;
        for a in 0..3 {
            for c in 0..3 {
                let (mut up, mut um) = (u.clone(), u.clone());
                up[a][c] += h;
                um[a][c] -= h;
                let fd = (s.energy(&x, &up) - s.energy(&x, &um)) / (2.0 * h);
                assert!((fd - f[a][c]).abs() < 1e-8, "node {a} comp {c}: {fd} vs {}", f[a][c]);
            }
        }
        // scale −1 removes exactly what scale 1 added.
        s.add_forces_into(&x, &u, -1.0, &mut f);
        assert!(f.iter().all(|v| v.norm() < 1e-14));
    }

    /// The residual is the distance along `d` of the material point from the target;
    /// moving every node by t along d moves it by t.
    #[test]
    fn residual_is_measured_along_the_direction() {
        let (s, d) = (spring(), Vector3::new(0.0, 0.6, 0.8));
        let x = points();
        let p: Vector3<f64> = x[0].coords * 0.2 + x[1].coords * 0.3 + x[2].coords * 0.5;
        let zero = vec![Vector3::zeros(); 3];
        assert!((s.residual(&x, &zero) - (d.dot(&p) - 1.5)).abs() < 1e-15);
        let t = 0.7;
        let moved = vec![d * t; 3];
        assert!((s.residual(&x, &moved) - s.residual(&x, &zero) - t).abs() < 1e-14);
    }

    /// Gershgorin's bound is at least the largest eigenvalue of one spring's Hessian,
    /// `k |β|² |d|²`, spread over its nodes.
    #[test]
    fn the_stiffness_bound_covers_the_hessian() {
        let mut s = Springs::new();
        s.push(spring());
        let mut bound = vec![0.0; 3];
        s.add_stiffness_bound_into(&mut bound);
        let beta2: f64 = [0.2f64, 0.3, 0.5].iter().map(|b| b * b).sum();
        let largest = 4.0 * beta2;
        assert!(bound.iter().cloned().fold(0.0, f64::max) >= largest);
        assert_eq!(bound, vec![4.0 * 0.2, 4.0 * 0.3, 4.0 * 0.5]);
    }
}
