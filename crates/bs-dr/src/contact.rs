//! The contact seam: the solver sees contact only through [`Contact`], called after every
//! step. `bs-dr` knows nothing of buckets, triangles or closest points; `bs-contact`
//! implements this trait and `bs-cli` composes the two.

use bs_mesh::Point3;

/// What a contact handler did in one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactReport {
    /// Number of nodes moved back onto the constraint surface in this step.
    pub nodes_in_contact: usize,
    /// Largest penetration found (distance moved) in this step.
    pub max_penetration: f64,
}

/// Kinematic constraint applied after every solver step.
pub trait Contact {
    /// `positions` are the current coordinates of ALL mesh nodes (reference + displacement),
    /// indexed like Mesh::nodes. Move nodes that violate the constraint; return a report.
    fn enforce(&mut self, positions: &mut [Point3<f64>]) -> ContactReport;
}

/// The null contact: moves nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoContact;

impl Contact for NoContact {
    fn enforce(&mut self, _positions: &mut [Point3<f64>]) -> ContactReport {
        ContactReport::default()
    }
}
