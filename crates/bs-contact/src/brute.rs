//! Brute-force handler: exact point–triangle distance to every face. The reference for
//! tests.

use std::sync::Arc;

use bs_mesh::TriSurface;
use nalgebra::Point3;

use crate::ContactError;
use crate::enforce::{ClosestPoint, Projection};
use crate::geometry::closest_point_triangle;
use crate::master::MasterSurface;

/// Exact closest point by testing every face: O(faces) per query.
#[derive(Debug, Clone)]
pub struct BruteForce {
    master: Arc<MasterSurface>,
}

impl BruteForce {
    /// Validates the skull and builds the handler.
    pub fn new(surface: &TriSurface) -> Result<Self, ContactError> {
        Ok(Self::from_master(Arc::new(MasterSurface::new(surface)?)))
    }

    /// Builds the handler on an already validated master surface.
    pub fn from_master(master: Arc<MasterSurface>) -> Self {
        Self { master }
    }

    /// The master surface.
    pub fn master(&self) -> &MasterSurface {
        &self.master
    }

    /// Exact closest point of the surface to `p` (first face wins on exact ties) with the
    /// paper's verdict at that point.
    pub fn project(&self, p: &Point3<f64>) -> Projection {
        let m = &*self.master;
        let mut best = (f64::INFINITY, Point3::origin(), crate::Feature::Face(0));
        for (t, tri) in m.triangles.iter().enumerate() {
            let (q, region) = closest_point_triangle(
                p,
                &m.vertices[tri[0] as usize],
                &m.vertices[tri[1] as usize],
                &m.vertices[tri[2] as usize],
            );
            let d2 = (q - p).norm_squared();
            if d2 < best.0 {
                best = (d2, q, m.feature_of(t as u32, region));
            }
        }
        let outside = m.is_outside(p, &best.1, best.2);
        let dist = best.0.sqrt();
        Projection {
            point: best.1,
            distance: if outside { -dist } else { dist },
            outside,
            feature: Some(best.2),
        }
    }
}

impl ClosestPoint for BruteForce {
    fn closest(&mut self, _slave: usize, p: &Point3<f64>) -> Option<Projection> {
        // A non-finite position (a diverged step) has no closest point: leave it alone.
        p.coords.iter().all(|x| x.is_finite()).then(|| self.project(p))
    }

    fn name(&self) -> &'static str {
        "brute-force"
    }
}
