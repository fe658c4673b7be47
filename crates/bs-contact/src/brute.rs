//! Brute-force handler: exact point–triangle distance to every face. The reference for
//! tests.

use std::sync::Arc;

use bs_mesh::TriSurface;
use nalgebra::Point3;

use crate::ContactError;
use crate::master::MasterSurface;
use crate::query::{ClosestPoint, Projection};

/// Exact closest point by testing every face: O(faces) per query
/// ([`MasterSurface::project_exact`] behind the [`ClosestPoint`] seam).
#[derive(Debug, Clone)]
pub struct BruteForce {
    master: Arc<MasterSurface>,
}

impl BruteForce {
    /// Validates the skull and builds the handler.
    pub fn new(surface: &TriSurface) -> Result<Self, ContactError> {
        Ok(Self::from_master(Arc::new(MasterSurface::new(surface)?)))
    }

    /// Builds the handler on an already validated (shared) master surface.
    pub fn from_master(master: Arc<MasterSurface>) -> Self {
        Self { master }
    }

    /// The master surface.
    pub fn master(&self) -> &MasterSurface {
        &self.master
    }

    /// Exact closest point of the surface to `p` (first face wins on exact ties) with the
    /// paper's verdict at that point. A non-finite `p` has none: it gets an infinite distance
    /// at its own position, inside, with no feature.
    pub fn project(&self, p: &Point3<f64>) -> Projection {
        self.master.project_exact(p).unwrap_or(Projection {
            point: *p,
            signed_distance: f64::INFINITY,
            outside: false,
            feature: None,
        })
    }
}

impl ClosestPoint for BruteForce {
    fn closest(&mut self, _slave: usize, p: &Point3<f64>) -> Option<Projection> {
        // A non-finite position (a diverged step) has no closest point: leave it alone.
        self.master.project_exact(p)
    }

    fn name(&self) -> &'static str {
        "brute-force"
    }
}
