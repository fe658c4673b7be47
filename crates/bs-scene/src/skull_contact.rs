//! The adapter between the two seams: bs-contact's enforcement loop seen through bs-dr's
//! [`bs_dr::Contact`] trait, with the time it spends kept for the run's report.

use std::sync::Arc;

use bs_contact::{ClosestPoint, Enforcer, Feature, Handler, ParryContact};
use bs_dr::{ContactProjection, ContactReport, SurfaceFeature};

/// bs-contact's enforcement loop seen through bs-dr's contact seam; it also keeps the time
/// spent in contact so a run can report its share.
#[derive(Debug)]
pub struct SkullContact {
    pub(crate) enforcer: Enforcer<Handler>,
    /// Exact closest points at any distance (parry's BVH and the exact point–triangle
    /// projection), for the Newton–Krylov solver's queries beyond the handler's reach.
    pub(crate) exact: Arc<ParryContact>,
    /// Wall time spent in contact since the start of the current solve (reset by each
    /// solve, so that a live session's update reports its own).
    pub elapsed: std::time::Duration,
}

impl bs_dr::Contact for SkullContact {
    fn enforce(&mut self, positions: &mut [bs_mesh::Point3<f64>]) -> ContactReport {
        let start = std::time::Instant::now();
        let r = self.enforcer.enforce(positions);
        self.elapsed += start.elapsed();
        ContactReport { nodes_in_contact: r.nodes_in_contact, max_penetration: r.max_penetration }
    }

    fn nodes(&self) -> &[usize] {
        self.enforcer.slaves()
    }

    fn project(&mut self, k: usize, p: &bs_mesh::Point3<f64>) -> Option<ContactProjection> {
        let start = std::time::Instant::now();
        // The handler's own search first: it certifies most points inside at no cost and is
        // exact within its reach; beyond it, the exact projection.
        let handler = self.enforcer.handler_mut();
        let reach = handler.reach();
        let fast = handler.closest(k, p);
        let proj = match fast {
            None if p.coords.iter().all(|x| x.is_finite()) => {
                self.elapsed += start.elapsed();
                return Some(ContactProjection {
                    point: *p,
                    outside: false,
                    feature: SurfaceFeature::Vertex,
                });
            }
            Some(proj) if proj.signed_distance.abs() <= reach && proj.feature.is_some() => {
                Some(proj)
            }
            _ => self.exact.project_exact(p),
        };
        let master = self.exact.master();
        let result = proj.and_then(|proj| {
            let feature = match proj.feature? {
                Feature::Face(f) => SurfaceFeature::Face(master.face_normals()[f as usize]),
                Feature::Edge(e) => {
                    let [a, b] = master.edges()[e as usize];
                    let t = master.vertices()[b as usize] - master.vertices()[a as usize];
                    SurfaceFeature::Edge(t.normalize())
                }
                Feature::Node(_) => SurfaceFeature::Vertex,
            };
            Some(ContactProjection { point: proj.point, outside: proj.outside, feature })
        });
        self.elapsed += start.elapsed();
        result
    }
}
