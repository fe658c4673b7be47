//! Kinematic brain–skull contact against a rigid closed triangle surface.
//!
//! After every solver step each brain-surface (slave) node that has left the skull cavity
//! is moved to the closest point of the skull (master) surface: bucket search for the
//! closest master node, local search over the faces and edges around it plus precomputed
//! per-node lists of additional faces and edges (Joldes et al., brain–skull contact paper,
//! section 3).
//!
//! Architecture invariant: this crate knows triangle surfaces and points. It knows nothing
//! of elements, materials or Dynamic Relaxation, and must not depend on `bs-dr`.
//!
//! Handlers (all implement [`ClosestPoint`]; [`Enforcer`] runs the shared loop):
//! * [`PaperContact`]: the paper's algorithm (see [`paper`] for how each sentence of §3.2 is
//!   read).
//! * [`CoherentContact`]: the paper's algorithm with per-slave temporal coherence; provably
//!   the same corrections, fewer searches.
//! * [`BruteForce`]: every face, exact distance; the test reference.
//! * [`ParryContact`]: parry3d-f64's `TriMesh` projection; the off-the-shelf baseline.
//! * [`NoContact`]: never corrects anything.
//!
//! Sign convention: signed distance is positive inside the cavity, negative outside.
//!
//! ```
//! use bs_contact::{shapes, Enforcer, PaperContact, PaperParams};
//! use bs_mesh::Point3;
//!
//! let skull = shapes::sphere(200); // any closed, outward-oriented TriSurface
//! let handler = PaperContact::new(&skull, PaperParams::default()).unwrap();
//! let mut positions = vec![Point3::new(0.0, 0.0, 0.5), Point3::new(0.0, 0.0, 1.05)];
//! let mut contact = Enforcer::new(handler, vec![0, 1], positions.len()).unwrap();
//! let report = contact.enforce(&mut positions);
//! assert_eq!(report.nodes_in_contact, 1); // node 1 was outside and is now on the skull
//! assert_eq!(positions[0], Point3::new(0.0, 0.0, 0.5)); // inside: untouched
//! ```

mod brute;
mod coherent;
mod enforce;
mod error;
pub mod geometry;
pub mod grid;
mod master;
pub mod paper;
mod parry_handler;
pub mod shapes;

pub use brute::BruteForce;
pub use coherent::{CoherenceStats, CoherentContact};
pub use enforce::{
    ClosestPoint, EnforceReport, Enforcer, GapRow, OutsideNode, Projection, check_initial, gap,
};
pub use error::ContactError;
pub use master::{Feature, MasterSurface, NodeNormalRule};
pub use paper::{AdditionalLists, PaperContact, PaperParams};
pub use parry_handler::ParryContact;

/// The null handler: never finds a slave outside, never moves anything.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoContact;

impl ClosestPoint for NoContact {
    fn closest(&mut self, _slave: usize, _p: &bs_mesh::Point3<f64>) -> Option<Projection> {
        None
    }

    fn reach(&self) -> f64 {
        0.0
    }

    fn name(&self) -> &'static str {
        "none"
    }
}
