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
//! tetrahedron for a landmark). A point-to-plane term of a scanned point is one spring
//! along the face normal; a point-to-point landmark, three. Between two linearisations the
//! springs are fixed, so the data force `Σ k r β_j d` is linear in `u` and its Jacobian
//! the Gauss–Newton Hessian `Σ k (β ⊗ d)(β ⊗ d)ᵀ`: a Newton step of the sum is the
//! Gauss–Newton step of the data and the Newton step of the model, and an iteratively
//! reweighted robust fit is a change of `k` at the next linearisation.
//!
//! The correspondences and weights (closest points, robust statistics, rigid corrections)
//! are the term's own business, not the solver's: bs-dr knows no geometry. [`NoData`] is
//! the null term.

use bs_mesh::{Point3, Vector3};

/// One term of a linearised data energy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Spring {
    /// `½ k (d · Σ_j β_j x_j − c)²`: a material point (nodes and weights `β_j`) held along a
    /// fixed unit direction `d` at `c` (a landmark's three axes; a point matched on an edge
    /// of the patch).
    Along {
        /// The nodes of the material point (unused slots have weight 0).
        nodes: [usize; 4],
        /// Their weights `β_j` (barycentric coordinates of the material point).
        weights: [f64; 4],
        /// The unit direction `d` the term measures along.
        direction: Vector3<f64>,
        /// The target `c`: the measured position's coordinate along `d`.
        target: f64,
        /// The stiffness `k` (force per length).
        stiffness: f64,
    },
    /// `½ k (n · (x_a − p))²` with `n` the unit normal of the triangle `(x_a, x_b, x_c)` at
    /// the current positions: the squared distance of the measured point `p` from the
    /// triangle's plane. Its gradient is `k r β_j n` on corner `j` (`β` the barycentric
    /// coordinates of `p`'s projection on the plane), like an `Along` spring's; unlike one,
    /// its Hessian includes the turning of the face, which the solver's difference Jacobian
    /// sees: where the data pull hard, a fixed direction misses a term as large as the
    /// model's own stiffness and the fit converges only linearly.
    Plane {
        /// The triangle's nodes.
        nodes: [usize; 3],
        /// The measured point.
        point: Point3<f64>,
        /// The stiffness `k` (force per length).
        stiffness: f64,
    },
}

/// A triangle's unit normal, and the barycentric coordinates of `p`'s projection on its
/// plane; `None` for a degenerate triangle.
fn plane_of(x: [Point3<f64>; 3], p: &Point3<f64>) -> Option<(Vector3<f64>, [f64; 3])> {
    let (e1, e2) = (x[1] - x[0], x[2] - x[0]);
    let m = e1.cross(&e2);
    let area2 = m.norm_squared();
    if area2 <= 0.0 || !area2.is_finite() {
        return None;
    }
    let d = p - x[0];
    let w1 = d.cross(&e2).dot(&m) / area2;
    let w2 = e1.cross(&d).dot(&m) / area2;
    Some((m / area2.sqrt(), [1.0 - w1 - w2, w1, w2]))
}

/// A spring's residual, its direction and the nodes and weights of its material point (the
/// residual's gradient at node `j` is `β_j d`).
type Gradient = (f64, Vector3<f64>, [usize; 4], [f64; 4]);

impl Spring {
    /// The stiffness `k`.
    pub fn stiffness(&self) -> f64 {
        match *self {
            Spring::Along { stiffness, .. } | Spring::Plane { stiffness, .. } => stiffness,
        }
    }

    /// The residual at the displacements `u` (0 for a degenerate `Plane`).
    pub fn residual(&self, reference: &[Point3<f64>], u: &[Vector3<f64>]) -> f64 {
        self.gradient(reference, u).map_or(0.0, |(r, ..)| r)
    }

    /// The residual, its direction and the weights of the nodes (the gradient of the
    /// residual at node `j` is `β_j d`).
    fn gradient(&self, reference: &[Point3<f64>], u: &[Vector3<f64>]) -> Option<Gradient> {
        match *self {
            Spring::Along { nodes, weights, direction, target, .. } => {
                let mut s = -target;
                for (&a, &b) in nodes.iter().zip(&weights) {
                    if b != 0.0 {
                        s += b * direction.dot(&(reference[a].coords + u[a]));
                    }
                }
                Some((s, direction, nodes, weights))
            }
            Spring::Plane { nodes, point, .. } => {
                let x = nodes.map(|a| reference[a] + u[a]);
                let (n, b) = plane_of(x, &point)?;
                let r = n.dot(&(x[0] - point));
                Some((r, n, [nodes[0], nodes[1], nodes[2], 0], [b[0], b[1], b[2], 0.0]))
            }
        }
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
            let Some((r, d, nodes, weights)) = s.gradient(reference, u) else { continue };
            let g = d * (scale * s.stiffness() * r);
            for (&a, &b) in nodes.iter().zip(&weights) {
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
                0.5 * s.stiffness() * r * r
            })
            .sum()
    }

    /// Adds to `out[a]` a bound on the springs' stiffness at node `a` (the row sums of the
    /// absolute Hessian, Gershgorin's bound on its largest eigenvalue): what an explicit
    /// solver's masses must carry for its step to stay stable.
    ///
    /// A `Plane` spring's weights are those at `positions`, the face's turning left out
    /// (its term is the residual over the face's size: small where an explicit solver
    /// steps).
    pub fn add_stiffness_bound_into(&self, positions: &[Point3<f64>], out: &mut [f64]) {
        for s in &self.terms {
            let (nodes, weights) = match *s {
                Spring::Along { nodes, weights, .. } => (nodes, weights),
                Spring::Plane { nodes, point, .. } => {
                    let x = nodes.map(|a| positions[a]);
                    let Some((_, b)) = plane_of(x, &point) else { continue };
                    ([nodes[0], nodes[1], nodes[2], 0], [b[0], b[1], b[2], 0.0])
                }
            };
            let total: f64 = weights.iter().map(|b| b.abs()).sum();
            for (&a, &b) in nodes.iter().zip(&weights) {
                if b != 0.0 {
                    out[a] += s.stiffness() * b.abs() * total;
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
        Spring::Along {
            nodes: [0, 1, 2, 0],
            weights: [0.2, 0.3, 0.5, 0.0],
            direction,
            target,
            stiffness,
        }
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
        // The distance of a point from the plane of the three nodes, the plane turning with
        // them: its force is still the energy's gradient.
        s.push(Spring::Plane {
            nodes: [0, 1, 2],
            point: Point3::new(0.3, 0.2, 2.2),
            stiffness: 2.5,
        });
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

    /// A plane spring's residual is the signed distance of its point from the triangle's
    /// plane: a unit right triangle in z = 0 and a point at height 0.4 above it.
    #[test]
    fn a_plane_spring_measures_the_distance_from_the_face() {
        let x = vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)];
        let s =
            Spring::Plane { nodes: [0, 1, 2], point: Point3::new(0.2, 0.3, 0.4), stiffness: 1.0 };
        let zero = vec![Vector3::zeros(); 3];
        assert!((s.residual(&x, &zero) + 0.4).abs() < 1e-15);
        // Lift the face by 0.4: the point is on it.
        assert!(s.residual(&x, &[Vector3::new(0.0, 0.0, 0.4); 3]).abs() < 1e-15);
        // Its force: k r β_j n with β = (0.5, 0.2, 0.3).
        let mut springs = Springs::new();
        springs.push(s);
        let mut f = vec![Vector3::zeros(); 3];
        springs.add_forces_into(&x, &zero, 1.0, &mut f);
        for (j, b) in [0.5, 0.2, 0.3].into_iter().enumerate() {
            assert!((f[j] - Vector3::new(0.0, 0.0, -0.4 * b)).norm() < 1e-15, "{j}: {}", f[j]);
        }
    }

    /// Gershgorin's bound is at least the largest eigenvalue of one spring's Hessian,
    /// `k |β|² |d|²`, spread over its nodes.
    #[test]
    fn the_stiffness_bound_covers_the_hessian() {
        let mut s = Springs::new();
        s.push(spring());
        let mut bound = vec![0.0; 3];
        s.add_stiffness_bound_into(&points(), &mut bound);
        let beta2: f64 = [0.2f64, 0.3, 0.5].iter().map(|b| b * b).sum();
        let largest = 4.0 * beta2;
        assert!(bound.iter().cloned().fold(0.0, f64::max) >= largest);
        assert_eq!(bound, vec![4.0 * 0.2, 4.0 * 0.3, 4.0 * 0.5]);
    }
}
