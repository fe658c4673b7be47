//! The handler chosen at run time: [`Algorithm`] names the algorithms (as a CLI flag or a
//! scene file does) and [`Handler`] dispatches to the one built.

use std::sync::Arc;

use nalgebra::Point3;

#[cfg(feature = "parry")]
use crate::ParryContact;
use crate::{
    BruteForce, ClosestPoint, CoherentContact, ContactError, MasterSurface, NullHandler,
    PaperContact, PaperParams, Projection,
};

/// The contact algorithms selectable by name (`paper`, `coherent`, `parry`, `brute-force`,
/// `none`), e.g. from a CLI flag, a scene file or a report (serde spells them so too).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Algorithm {
    /// [`PaperContact`].
    Paper,
    /// [`CoherentContact`] (default: same corrections as the paper's, fastest).
    #[default]
    Coherent,
    /// `ParryContact` (needs the `parry` feature, on by default).
    Parry,
    /// [`BruteForce`].
    BruteForce,
    /// [`NullHandler`].
    None,
}

impl Algorithm {
    /// All names accepted by [`FromStr`](std::str::FromStr).
    pub const NAMES: [&'static str; 5] = ["paper", "coherent", "parry", "brute-force", "none"];

    /// The name, as [`FromStr`](std::str::FromStr) reads it.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Paper => "paper",
            Algorithm::Coherent => "coherent",
            Algorithm::Parry => "parry",
            Algorithm::BruteForce => "brute-force",
            Algorithm::None => "none",
        }
    }
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

impl std::fmt::Display for Algorithm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
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
    #[cfg(feature = "parry")]
    Parry(ParryContact),
    /// Brute force.
    BruteForce(BruteForce),
    /// No contact.
    None(NullHandler),
}

impl Handler {
    /// Validates `skull` and builds the selected handler (`params` apply to the paper and
    /// coherent handlers).
    pub fn new(
        algorithm: Algorithm,
        skull: &bs_mesh::TriSurface,
        params: PaperParams,
    ) -> Result<Self, ContactError> {
        Self::from_master(algorithm, Arc::new(MasterSurface::new(skull)?), params)
    }

    /// Builds the selected handler on an already validated master surface, which it shares
    /// (build the surface once per skull and hand the same `Arc` to every handler). The
    /// parry handler needs the `parry` feature; without it, choosing it is an error.
    pub fn from_master(
        algorithm: Algorithm,
        master: Arc<MasterSurface>,
        params: PaperParams,
    ) -> Result<Self, ContactError> {
        Ok(match algorithm {
            Algorithm::Paper => Self::Paper(PaperContact::from_master(master, params)?),
            Algorithm::Coherent => Self::Coherent(CoherentContact::from_master(master, params)?),
            #[cfg(feature = "parry")]
            Algorithm::Parry => Self::Parry(ParryContact::from_master(master)?),
            #[cfg(not(feature = "parry"))]
            Algorithm::Parry => {
                return Err(ContactError::InvalidParameter(
                    "the parry handler needs bs-contact's `parry` feature".into(),
                ));
            }
            Algorithm::BruteForce => Self::BruteForce(BruteForce::from_master(master)),
            Algorithm::None => Self::None(NullHandler),
        })
    }

    /// The exact closest point at any distance with its feature (the Newton–Krylov solver's
    /// query): the paper's bucket grid for the paper and coherent handlers, parry's BVH for
    /// parry, every face for brute force. `None` for a non-finite point or the null handler.
    pub fn project_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        match self {
            Self::Paper(h) => h.project_exact(p),
            Self::Coherent(h) => h.paper().project_exact(p),
            #[cfg(feature = "parry")]
            Self::Parry(h) => h.project_exact(p),
            Self::BruteForce(h) => h.master().project_exact(p),
            Self::None(_) => None,
        }
    }

    /// The master surface of the handler (`None` for the null handler).
    pub fn master(&self) -> Option<&MasterSurface> {
        match self {
            Self::Paper(h) => Some(h.master()),
            Self::Coherent(h) => Some(h.paper().master()),
            #[cfg(feature = "parry")]
            Self::Parry(h) => Some(h.master()),
            Self::BruteForce(h) => Some(h.master()),
            Self::None(_) => None,
        }
    }
}

impl ClosestPoint for Handler {
    #[inline]
    fn closest(&mut self, slave: usize, p: &Point3<f64>) -> Option<Projection> {
        match self {
            Self::Paper(h) => h.closest(slave, p),
            Self::Coherent(h) => h.closest(slave, p),
            #[cfg(feature = "parry")]
            Self::Parry(h) => h.closest(slave, p),
            Self::BruteForce(h) => h.closest(slave, p),
            Self::None(h) => h.closest(slave, p),
        }
    }

    fn reach(&self) -> f64 {
        match self {
            Self::Paper(h) => h.reach(),
            Self::Coherent(h) => h.reach(),
            #[cfg(feature = "parry")]
            Self::Parry(h) => h.reach(),
            Self::BruteForce(h) => h.reach(),
            Self::None(h) => h.reach(),
        }
    }

    fn closest_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        self.project_exact(p)
    }

    fn name(&self) -> &'static str {
        match self {
            Self::Paper(h) => h.name(),
            Self::Coherent(h) => h.name(),
            #[cfg(feature = "parry")]
            Self::Parry(h) => h.name(),
            Self::BruteForce(h) => h.name(),
            Self::None(h) => h.name(),
        }
    }
}
