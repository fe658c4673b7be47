//! Baseline handler on parry3d-f64: `TriMesh` (built with the `ORIENTED` flag so that its
//! pseudo-normal inside test works) and its BVH closest-point query.

use std::sync::Arc;

use bs_mesh::TriSurface;
use nalgebra::Point3;
use parry3d_f64::math::Vector as PVec;
use parry3d_f64::query::{PointQuery, PointQueryWithLocation};
use parry3d_f64::shape::{TriMesh, TriMeshFlags};

use crate::ContactError;
use crate::master::MasterSurface;
use crate::query::{ClosestPoint, Projection};

/// Closest point and inside test from parry's `TriMesh` (the off-the-shelf baseline).
pub struct ParryContact {
    mesh: TriMesh,
    master: Arc<MasterSurface>,
}

impl std::fmt::Debug for ParryContact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ParryContact").field("triangles", &self.mesh.indices().len()).finish()
    }
}

impl ParryContact {
    /// Validates the skull with the same rules as the other handlers and builds the mesh.
    pub fn new(surface: &TriSurface) -> Result<Self, ContactError> {
        Self::from_master(Arc::new(MasterSurface::new(surface)?))
    }

    /// Builds the parry mesh on a validated master surface, which it shares (parry keeps its
    /// own copy of the vertices and triangles, in its own types).
    pub fn from_master(master: Arc<MasterSurface>) -> Result<Self, ContactError> {
        let vertices: Vec<PVec> =
            master.vertices().iter().map(|p| PVec::new(p.x, p.y, p.z)).collect();
        let mesh =
            TriMesh::with_flags(vertices, master.triangles().to_vec(), TriMeshFlags::ORIENTED)
                .map_err(|e| {
                    ContactError::InvalidParameter(format!("parry rejected the skull mesh: {e:?}"))
                })?;
        Ok(Self { mesh, master })
    }

    /// Closest point with its feature and the paper's verdict at it: parry's BVH finds the
    /// triangle, the exact point–triangle projection on it gives the feature. `None` for a
    /// non-finite point.
    pub fn project_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        if !p.coords.iter().all(|x| x.is_finite()) {
            return None;
        }
        let q = PVec::new(p.x, p.y, p.z);
        let (_, (part, _)) = self.mesh.project_local_point_and_get_location(q, false);
        let m = &*self.master;
        let t = part.min(m.triangles().len().saturating_sub(1) as u32);
        // The feature parry reports can be a neighbour of the exact one on ties: test the
        // triangle and its edge neighbours exactly.
        let neighbours =
            m.face_edges()[t as usize].into_iter().flat_map(|e| m.edge_faces()[e as usize]);
        m.project_on_faces(p, std::iter::once(t).chain(neighbours))
    }

    /// The master surface.
    pub fn master(&self) -> &MasterSurface {
        &self.master
    }

    /// Closest point with parry's inside flag (`solid = false`).
    pub fn project(&self, p: &Point3<f64>) -> Projection {
        let q = PVec::new(p.x, p.y, p.z);
        let proj = self.mesh.project_local_point(q, false);
        let r = Point3::new(proj.point.x, proj.point.y, proj.point.z);
        let dist = (r - p).norm();
        Projection {
            point: r,
            signed_distance: if proj.is_inside { dist } else { -dist },
            outside: !proj.is_inside,
            feature: None,
        }
    }
}

impl ClosestPoint for ParryContact {
    fn closest(&mut self, _slave: usize, p: &Point3<f64>) -> Option<Projection> {
        // A non-finite position (a diverged step) has no closest point: leave it alone.
        p.coords.iter().all(|x| x.is_finite()).then(|| self.project(p))
    }

    fn name(&self) -> &'static str {
        "parry"
    }
}
