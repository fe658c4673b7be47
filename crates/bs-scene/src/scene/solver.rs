//! `[contact]` and `[solver]`: the contact handler and the solver with its settings.

use std::path::PathBuf;

use serde::Deserialize;

/// Contact handler names: bs-contact's own (`none` is refused in a scene: a scene without
/// contact has no `[contact]` table).
pub use bs_contact::Algorithm;

/// The rigid skull.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Contact {
    /// Closed, outward-oriented triangle surface (.stl, .obj, .off).
    pub skull: PathBuf,
    /// Handler; default `paper`.
    #[serde(default = "default_algorithm", deserialize_with = "handler")]
    pub algorithm: Algorithm,
}

fn default_algorithm() -> Algorithm {
    Algorithm::Paper
}

/// A handler's name; `none` is an error naming the fix.
fn handler<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Algorithm, D::Error> {
    match Algorithm::deserialize(d)? {
        Algorithm::None => Err(serde::de::Error::custom(
            "algorithm \"none\" is not a handler: to solve without contact, remove the \
             [contact] table; the handlers are paper, coherent, parry and brute-force",
        )),
        a => Ok(a),
    }
}

/// Solver kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Semismooth Newton–Krylov with the two-level preconditioner (the default): any
    /// element, kinematic contact linearised on its active set.
    #[default]
    #[serde(rename = "newton-krylov")]
    NewtonKrylov,
    /// Dynamic Relaxation (the paper's solver; the baseline).
    Dr,
    /// Static Newton–Raphson with a direct factorisation (reference; T4/H8, no contact).
    Newton,
}

impl SolverKind {
    /// The name used in scene files and reports.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::NewtonKrylov => "newton-krylov",
            SolverKind::Dr => "dr",
            SolverKind::Newton => "newton",
        }
    }
}

/// Solver settings.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Solver {
    /// Default `newton-krylov`.
    #[serde(default = "default_solver")]
    pub kind: SolverKind,
    /// Error-estimate tolerance in mesh length units; default 1e-3.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// DR steps of the 3-4-5 load ramp; default 200 (DR only). Large displacements on coarse meshes
    /// need a longer ramp (the prescribed nodes otherwise outrun their neighbours and
    /// invert elements).
    #[serde(default = "default_ramp_steps")]
    pub ramp_steps: usize,
    /// The iteration budget: Newton iterations over all load levels (newton-krylov, default
    /// 300) or DR steps (dr, default 200 000); not used by `newton`. Extreme loads (the
    /// 40 mm ellipsoid on a fine mesh) may need more.
    #[serde(default)]
    pub max_steps: Option<usize>,
}

fn default_ramp_steps() -> usize {
    bs_dr::DrParams::default().ramp_steps
}

fn default_solver() -> SolverKind {
    SolverKind::NewtonKrylov
}

fn default_tolerance() -> f64 {
    1e-3
}

impl Default for Solver {
    fn default() -> Self {
        Solver {
            kind: default_solver(),
            tolerance: default_tolerance(),
            ramp_steps: default_ramp_steps(),
            max_steps: None,
        }
    }
}

display_by_name!(SolverKind);
