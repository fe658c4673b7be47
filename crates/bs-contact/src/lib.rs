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
//! Handlers (all implement [`ClosestPoint`], the one query of [`query`]; [`Enforcer`] runs
//! the shared loop; [`Handler`] picks one by [`Algorithm`] name at run time):
//! * [`PaperContact`]: the paper's algorithm (see [`paper`] for how each sentence of §3.2 is
//!   read).
//! * [`CoherentContact`]: the paper's algorithm with per-slave temporal coherence; provably
//!   the same corrections, fewer searches.
//! * [`BruteForce`]: every face, exact distance; the test reference.
//! * `ParryContact`: parry3d-f64's `TriMesh` projection; the off-the-shelf baseline (the
//!   `parry` feature, on by default).
//! * [`NullHandler`]: never corrects anything.
//!
//! Every handler shares one validated [`MasterSurface`] (`Arc`), built once per skull; its
//! [`project_exact`](MasterSurface::project_exact) is the exact closest point at any
//! distance that the [`diagnostics`] ([`check_initial`], [`gap`]) and the tests rely on.
//!
//! Sign convention: `signed_distance` (of [`Projection`], [`GapRow`], [`OutsideNode`]) is
//! positive inside the cavity, negative outside.
//!
//! Features: `parry` (default) builds the parry3d-f64 baseline handler; `testing` exposes
//! the random closed test surfaces (`shapes`) to this crate's tests and to bs-study (its
//! validation and stability cases and the contact benchmark); it is not library API.
//!
//! Files:
//! * `query.rs`: `ClosestPoint`, `Projection` and `Feature`, the one query every handler
//!   answers;
//! * `enforce.rs`: `Enforcer` and `EnforceReport`, the shared enforcement loop;
//! * `master.rs`: `MasterSurface`, the validated skull with its precomputed topology and
//!   normals (`NodeNormalRule`), and its exact projections;
//! * `paper/`: `PaperContact` and `PaperParams` (`mod.rs`) and the §3.2 additional lists
//!   with their predicates (`lists.rs`, `AdditionalLists`);
//! * `coherent.rs`: `CoherentContact`, the paper's handler with per-slave temporal coherence;
//! * `brute.rs`: `BruteForce`, every face, the test reference;
//! * `parry_handler.rs`: `ParryContact` (the `parry` feature);
//! * `null.rs`: `NullHandler`;
//! * `handler.rs`: `Algorithm` and `Handler`, the run-time choice by name;
//! * `diagnostics.rs`: `check_initial` and `gap`, exact at any distance;
//! * `patch.rs`: `Patch`, the exact closest point on an open, moving triangle patch;
//! * `grid.rs`: `BucketGrid`, the uniform bucket grid over a point set;
//! * `geometry.rs`: closest points on triangles and segments, circumcentres;
//! * `error.rs`: `ContactError`;
//! * `shapes.rs`: the random closed test surfaces (tests and the `testing` feature).
//!
//! ```
//! use bs_contact::bs_mesh::{Point3, TriSurface};
//! use bs_contact::{Enforcer, PaperContact, PaperParams};
//!
//! // Any closed, outward-oriented triangle surface: here an octahedron of "radius" 1.
//! let skull = TriSurface {
//!     vertices: [[1., 0., 0.], [-1., 0., 0.], [0., 1., 0.], [0., -1., 0.], [0., 0., 1.], [0., 0., -1.]]
//!         .map(Point3::from)
//!         .to_vec(),
//!     triangles: vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]],
//! };
//! let handler = PaperContact::new(&skull, PaperParams::default()).unwrap();
//! let mut positions = vec![Point3::new(0.0, 0.0, 0.5), Point3::new(0.0, 0.0, 1.05)];
//! let mut contact = Enforcer::new(handler, vec![0, 1], positions.len()).unwrap();
//! let report = contact.enforce(&mut positions);
//! assert_eq!(report.nodes_in_contact, 1); // node 1 was outside and is now on the skull
//! assert_eq!(positions[0], Point3::new(0.0, 0.0, 0.5)); // inside: untouched
//! assert_eq!(positions[1], Point3::new(0.0, 0.0, 1.0));
//! ```
//!
//! Choosing the algorithm by name (as the CLI's `--algorithm` does) on one shared master
//! surface, and computing gaps:
//!
//! ```
//! use std::sync::Arc;
//!
//! use bs_contact::bs_mesh::{Point3, TriSurface};
//! use bs_contact::{gap, Algorithm, Handler, MasterSurface, PaperParams};
//!
//! let skull = TriSurface {
//!     vertices: [[1., 0., 0.], [-1., 0., 0.], [0., 1., 0.], [0., -1., 0.], [0., 0., 1.], [0., 0., -1.]]
//!         .map(Point3::from)
//!         .to_vec(),
//!     triangles: vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]],
//! };
//! let master = Arc::new(MasterSurface::new(&skull).unwrap()); // validated once, shared
//! let algorithm: Algorithm = "coherent".parse().unwrap();
//! let mut handler = Handler::from_master(algorithm, master.clone(), PaperParams::default()).unwrap();
//! let rows = gap(&mut handler, &master, &[Point3::new(0.0, 0.0, 0.0)]);
//! // The centre of the octahedron: inside, 1/√3 from every face.
//! assert!(!rows[0].outside);
//! assert!((rows[0].signed_distance - 1.0 / 3f64.sqrt()).abs() < 1e-12);
//! ```

mod brute;
mod coherent;
pub mod diagnostics;
mod enforce;
mod error;
pub mod geometry;
pub mod grid;
mod handler;
mod master;
mod null;
pub mod paper;
#[cfg(feature = "parry")]
mod parry_handler;
pub mod patch;
pub mod query;
#[cfg(any(test, feature = "testing"))]
pub mod shapes;

/// The mesh crate this one reads surfaces from, re-exported so that callers (and the examples
/// above) need no separate dependency for `TriSurface` and `Point3`.
pub use bs_mesh;
/// The linear algebra of every point and vector here.
pub use nalgebra;

pub use brute::BruteForce;
pub use coherent::{CoherenceStats, CoherentContact};
pub use diagnostics::{GapRow, OutsideNode, check_initial, gap};
pub use enforce::{EnforceReport, Enforcer};
pub use error::ContactError;
pub use handler::{Algorithm, Handler};
pub use master::{MasterSurface, NodeNormalRule};
pub use null::NullHandler;
pub use paper::{AdditionalLists, PaperContact, PaperParams};
#[cfg(feature = "parry")]
pub use parry_handler::ParryContact;
pub use patch::{Patch, PatchPoint};
pub use query::{ClosestPoint, Feature, Projection};
