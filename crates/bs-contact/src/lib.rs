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
//!
//! Choosing the algorithm by name (as the CLI's `--algorithm` does) and computing gaps:
//!
//! ```
//! use bs_contact::{gap, shapes, Algorithm, Handler, MasterSurface, PaperParams};
//! use bs_mesh::Point3;
//!
//! let skull = shapes::sphere(200);
//! let algorithm: Algorithm = "coherent".parse().unwrap();
//! let mut handler = Handler::new(algorithm, &skull, PaperParams::default()).unwrap();
//! let master = MasterSurface::new(&skull).unwrap();
//! let rows = gap(&mut handler, &master, &[Point3::new(0.0, 0.0, 0.0)]);
//! // The centre of the unit sphere mesh: inside, a bit less than 1 from the skull.
//! assert!(!rows[0].outside && rows[0].signed_distance > 0.95 && rows[0].signed_distance < 1.0);
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

/// The contact algorithms selectable by name (`paper`, `coherent`, `parry`, `brute-force`,
/// `none`), e.g. from a CLI flag or a scene file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Algorithm {
    /// [`PaperContact`].
    Paper,
    /// [`CoherentContact`] (default: same corrections as the paper's, fastest).
    #[default]
    Coherent,
    /// [`ParryContact`].
    Parry,
    /// [`BruteForce`].
    BruteForce,
    /// [`NoContact`].
    None,
}

impl Algorithm {
    /// All names accepted by [`FromStr`](std::str::FromStr).
    pub const NAMES: [&'static str; 5] = ["paper", "coherent", "parry", "brute-force", "none"];
}

impl std::str::FromStr for Algorithm {
    type Err = ContactError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s {
            "paper" => Self::Paper,
            "coherent" => Self::Coherent,
            "parry" => Self::Parry,
            "brute-force" => Self::BruteForce,
            "none" => Self::None,
            other => {
                return Err(ContactError::InvalidParameter(format!(
                    "unknown contact algorithm '{other}'; expected one of {}",
                    Self::NAMES.join(", ")
                )));
            }
        })
    }
}

/// A handler chosen at run time; dispatches to the selected algorithm.
#[derive(Debug)]
pub enum Handler {
    /// The paper's algorithm.
    Paper(PaperContact),
    /// The paper's algorithm with temporal coherence.
    Coherent(CoherentContact),
    /// parry3d-f64 baseline.
    Parry(ParryContact),
    /// Brute force.
    BruteForce(BruteForce),
    /// No contact.
    None(NoContact),
}

impl Handler {
    /// Validates `skull` and builds the selected handler (`params` apply to the paper and
    /// coherent handlers).
    pub fn new(
        algorithm: Algorithm,
        skull: &bs_mesh::TriSurface,
        params: PaperParams,
    ) -> Result<Self, ContactError> {
        let master = std::sync::Arc::new(MasterSurface::new(skull)?);
        Ok(match algorithm {
            Algorithm::Paper => Self::Paper(PaperContact::from_master(master, params)?),
            Algorithm::Coherent => Self::Coherent(CoherentContact::from_master(master, params)?),
            Algorithm::Parry => Self::Parry(ParryContact::from_master(&master)?),
            Algorithm::BruteForce => Self::BruteForce(BruteForce::from_master(master)),
            Algorithm::None => Self::None(NoContact),
        })
    }
}

impl Handler {
    /// The exact closest point at any distance with its feature (the Newton–Krylov solver's
    /// query): the paper's bucket grid for the paper and coherent handlers, parry's BVH for
    /// parry, every face for brute force. `None` for a non-finite point or the null handler.
    pub fn project_exact(&self, p: &bs_mesh::Point3<f64>) -> Option<Projection> {
        match self {
            Self::Paper(h) => h.project_exact(p),
            Self::Coherent(h) => h.paper().project_exact(p),
            Self::Parry(h) => h.project_exact(p),
            Self::BruteForce(h) => p.coords.iter().all(|x| x.is_finite()).then(|| h.project(p)),
            Self::None(_) => None,
        }
    }

    /// The master surface of the handler (`None` for the null handler).
    pub fn master(&self) -> Option<&MasterSurface> {
        match self {
            Self::Paper(h) => Some(h.master()),
            Self::Coherent(h) => Some(h.paper().master()),
            Self::Parry(h) => Some(h.master()),
            Self::BruteForce(h) => Some(h.master()),
            Self::None(_) => None,
        }
    }
}

impl ClosestPoint for Handler {
    #[inline]
    fn closest(&mut self, slave: usize, p: &bs_mesh::Point3<f64>) -> Option<Projection> {
        match self {
            Self::Paper(h) => h.closest(slave, p),
            Self::Coherent(h) => h.closest(slave, p),
            Self::Parry(h) => h.closest(slave, p),
            Self::BruteForce(h) => h.closest(slave, p),
            Self::None(h) => h.closest(slave, p),
        }
    }

    fn reach(&self) -> f64 {
        match self {
            Self::Paper(h) => h.reach(),
            Self::Coherent(h) => h.reach(),
            Self::Parry(h) => h.reach(),
            Self::BruteForce(h) => h.reach(),
            Self::None(h) => h.reach(),
        }
    }

    fn name(&self) -> &'static str {
        match self {
            Self::Paper(h) => h.name(),
            Self::Coherent(h) => h.name(),
            Self::Parry(h) => h.name(),
            Self::BruteForce(h) => h.name(),
            Self::None(h) => h.name(),
        }
    }
}
