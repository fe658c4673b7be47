//! The contact seam: the solver sees contact only through [`Contact`]. `bs-dr` knows nothing
//! of buckets, triangles or closest points; `bs-scene` adapts `bs-contact`'s
//! handlers to this trait.
//!
//! Dynamic Relaxation calls [`Contact::enforce`] after every step (the paper's kinematic
//! contact). The Newton–Krylov solver takes larger steps and linearises the constraint: it
//! asks for the closest admissible point of trial points and the surface feature it lies on
//! ([`Contact::project`]), and calls `enforce` once on its converged answer.

use bs_mesh::{Point3, Vector3};

/// What a contact handler did in one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactReport {
    /// Number of nodes moved back onto the constraint surface in this step.
    pub nodes_in_contact: usize,
    /// Largest penetration found (distance moved) in this step.
    pub max_penetration: f64,
}

/// The feature of the constraint surface a closest point lies on, which sets the directions
/// in which a node touching it is held: a face holds its normal direction, an edge the plane
/// across it, a vertex every direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SurfaceFeature {
    /// Inside a flat face with this outward unit normal (triangle meshes).
    Face(Vector3<f64>),
    /// On a smooth curved surface with this outward unit normal and mean curvature (1/radius;
    /// positive where the admissible region is locally convex, as inside a spherical
    /// cavity). Analytic obstacles use it; the solver then includes the curvature's
    /// tangential stiffness in its linearisation.
    Curved {
        /// Outward unit normal.
        normal: Vector3<f64>,
        /// Mean curvature (1/length).
        curvature: f64,
    },
    /// On an edge with this unit direction.
    Edge(Vector3<f64>),
    /// On a vertex.
    Vertex,
}

impl SurfaceFeature {
    /// Orthonormal basis of the directions the feature constrains (1, 2 or 3 vectors) into
    /// `out`; returns how many.
    pub fn constrained_directions(&self, out: &mut [Vector3<f64>; 3]) -> usize {
        match *self {
            SurfaceFeature::Face(n) | SurfaceFeature::Curved { normal: n, .. } => {
                out[0] = n;
                1
            }
            SurfaceFeature::Edge(t) => {
                let a = if t.x.abs() < 0.6 { Vector3::x() } else { Vector3::y() };
                let b1 = (a - t * t.dot(&a)).normalize();
                out[0] = b1;
                out[1] = t.cross(&b1);
                2
            }
            SurfaceFeature::Vertex => {
                *out = [Vector3::x(), Vector3::y(), Vector3::z()];
                3
            }
        }
    }
}

/// The closest admissible point to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactProjection {
    /// The closest point of the constraint surface.
    pub point: Point3<f64>,
    /// Whether the query point is outside the admissible region (it violates the constraint).
    pub outside: bool,
    /// The surface feature `point` lies on.
    pub feature: SurfaceFeature,
}

/// Kinematic constraint applied by the solvers.
pub trait Contact {
    /// `positions` are the current coordinates of ALL mesh nodes (reference + displacement),
    /// indexed like Mesh::nodes. Move nodes that violate the constraint; return a report.
    fn enforce(&mut self, positions: &mut [Point3<f64>]) -> ContactReport;

    /// The nodes the constraint governs (indices into the positions). Default: none.
    fn nodes(&self) -> &[usize] {
        &[]
    }

    /// Closest admissible point to `p` for the `k`-th node of [`nodes`](Self::nodes), exact
    /// at any distance, with its surface feature. `None` means the handler cannot answer;
    /// solvers that linearise the contact then refuse the problem. Default: `None`.
    fn project(&mut self, k: usize, p: &Point3<f64>) -> Option<ContactProjection> {
        let _ = (k, p);
        None
    }
}

/// The null contact: moves nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoContact;

impl Contact for NoContact {
    fn enforce(&mut self, _positions: &mut [Point3<f64>]) -> ContactReport {
        ContactReport::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constrained_directions_are_orthonormal_and_exclude_the_edge() {
        let t = Vector3::new(0.3, -0.5, 0.8).normalize();
        let mut d = [Vector3::zeros(); 3];
        for f in
            [SurfaceFeature::Face(Vector3::z()), SurfaceFeature::Edge(t), SurfaceFeature::Vertex]
        {
            let k = f.constrained_directions(&mut d);
            for i in 0..k {
                assert!((d[i].norm() - 1.0).abs() < 1e-14);
                for j in 0..i {
                    assert!(d[i].dot(&d[j]).abs() < 1e-14);
                }
                if let SurfaceFeature::Edge(t) = f {
                    assert!(d[i].dot(&t).abs() < 1e-14);
                }
            }
        }
    }
}
