//! What a Newton–Krylov solve returns: [`NewtonKrylovInfo`] on success,
//! [`NewtonKrylovError`] otherwise, each converting into the common [`Report`] and
//! [`SolveError`] of the `Solver` trait.

use std::fmt;
use std::time::Duration;

use crate::assembly::Inversion;
use crate::contact::ContactReport;
use crate::dr::DrError;
use crate::solver::{
    Breakdown, ContinuationSummary, InvalidParam, LoadFailure, Report, SolveError,
};

/// What a converged Newton–Krylov solve did.
#[derive(Debug, Clone, PartialEq)]
pub struct NewtonKrylovInfo {
    /// Newton iterations over all load levels.
    pub iterations: usize,
    /// Load levels converged (1 when the whole load went in one increment).
    pub load_levels: usize,
    /// Failed attempts at a level retried with a smaller increment.
    pub cutbacks: usize,
    /// Rebuilds of the preconditioner on the deformed configuration.
    pub refreshes: usize,
    /// Dynamic Relaxation steps of the fallback (0 when it did not run).
    pub fallback_steps: usize,
    /// The last Newton correction `max|Δu|` (length units): the error estimate.
    pub err: f64,
    /// The tolerance it was compared with (length units).
    pub tolerance: f64,
    /// Nodes held on the surface at the end, and the largest penetration of any iterate.
    pub contact: ContactReport,
    /// Internal-force evaluations (residuals, line-search trials, Jacobian products).
    pub force_evaluations: usize,
    /// GMRES iterations.
    pub linear_iterations: usize,
    /// Where the time went.
    pub breakdown: Breakdown,
    /// Wall-clock time of the solve.
    pub elapsed: Duration,
}

impl From<NewtonKrylovInfo> for Report {
    fn from(i: NewtonKrylovInfo) -> Report {
        Report {
            solver: "newton-krylov",
            steps: i.iterations,
            err: i.err,
            tolerance: i.tolerance,
            contact: i.contact,
            force_evaluations: i.force_evaluations + i.fallback_steps,
            linear_iterations: i.linear_iterations,
            breakdown: i.breakdown,
            elapsed: i.elapsed,
            continuation: Some(ContinuationSummary {
                load_levels: i.load_levels,
                cutbacks: i.cutbacks,
                refreshes: i.refreshes,
                fallback_steps: i.fallback_steps,
            }),
        }
    }
}

/// Why a Newton–Krylov solve stopped without an answer. The messages are those of the
/// matching [`SolveError`] variants (each names the cause and the fix).
#[derive(Debug, Clone, PartialEq)]
pub enum NewtonKrylovError {
    /// A parameter is out of range.
    InvalidParams {
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// The loads were built for a different number of nodes.
    LoadMismatch {
        /// Model node count.
        expected: usize,
        /// Loads node count.
        got: usize,
    },
    /// The solver cannot run this problem (a preparation for other loads, a contact handler
    /// that cannot project).
    Unsupported {
        /// The unsupported feature.
        what: &'static str,
        /// What to do instead.
        fix: &'static str,
    },
    /// The preconditioner could not be built.
    Preconditioner {
        /// Why.
        reason: String,
    },
    /// The start state already has an inverted element.
    ElementInverted {
        /// Element index (mesh order).
        element: usize,
        /// External element id.
        element_id: u64,
        /// Its `det F`.
        jacobian: f64,
    },
    /// A displacement became NaN or infinite.
    NotFinite {
        /// Newton iteration.
        step: usize,
    },
    /// Displacements grew far beyond the prescribed ones.
    Diverged {
        /// Newton iteration.
        step: usize,
        /// Largest displacement magnitude.
        max_displacement: f64,
        /// The bound it exceeded.
        limit: f64,
    },
    /// The continuation could not carry the load (see [`SolveError::LoadNotCarried`]).
    LoadNotCarried {
        /// Load fraction of the last converged level.
        reached: f64,
        /// The full load's size (length units).
        load: f64,
        /// Why the next level failed.
        cause: LoadFailure,
        /// How the fallback stopped, if it ran.
        fallback: Option<DrError>,
    },
}

impl NewtonKrylovError {
    /// A short stable name of the error kind (that of the matching [`SolveError`]).
    pub fn kind(&self) -> &'static str {
        SolveError::from(self.clone()).kind()
    }

    pub(crate) fn inverted(inv: Inversion) -> Self {
        let Inversion { element, element_id, jacobian } = inv;
        NewtonKrylovError::ElementInverted { element, element_id, jacobian }
    }

    pub(crate) fn cannot_project() -> Self {
        NewtonKrylovError::Unsupported {
            what: "a contact handler that cannot project points",
            fix: "use a handler with exact projection, or the Dynamic Relaxation solver",
        }
    }
}

impl From<InvalidParam> for NewtonKrylovError {
    fn from(p: InvalidParam) -> Self {
        NewtonKrylovError::InvalidParams {
            name: p.name,
            value: p.value,
            requirement: p.requirement,
        }
    }
}

impl From<NewtonKrylovError> for SolveError {
    fn from(e: NewtonKrylovError) -> SolveError {
        use NewtonKrylovError as E;
        match e {
            E::InvalidParams { name, value, requirement } => {
                SolveError::InvalidParams { name, value, requirement }
            }
            E::LoadMismatch { expected, got } => SolveError::LoadMismatch { expected, got },
            E::Unsupported { what, fix } => {
                SolveError::Unsupported { solver: "newton-krylov", what, fix }
            }
            E::Preconditioner { reason } => SolveError::Preconditioner { reason },
            E::ElementInverted { element, element_id, jacobian } => {
                SolveError::ElementInverted { step: 0, element, element_id, jacobian }
            }
            E::NotFinite { step } => SolveError::NotFinite { step },
            E::Diverged { step, max_displacement, limit } => {
                SolveError::Diverged { step, max_displacement, limit }
            }
            E::LoadNotCarried { reached, load, cause, fallback } => SolveError::LoadNotCarried {
                reached,
                load,
                cause,
                fallback: fallback.map(|f| Box::new(f.into())),
            },
        }
    }
}

impl fmt::Display for NewtonKrylovError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        SolveError::from(self.clone()).fmt(f)
    }
}

impl std::error::Error for NewtonKrylovError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_load_not_carried_names_the_fraction_the_element_and_blames_the_mesh_only_with_proof() {
        let cause = LoadFailure::WouldInvert { element: 1233, element_id: 1234 };
        let e =
            NewtonKrylovError::LoadNotCarried { reached: 0.905, load: 40.0, cause, fallback: None };
        let text = e.to_string();
        assert!(text.starts_with("converged to 36.2 of 40 (90.5 % of the load)"), "{text}");
        assert!(text.contains("element 1233 (id 1234) would invert"), "{text}");
        assert!(!text.contains("mesh"), "{text}");
        assert_eq!(e.kind(), "LoadNotCarried");
        let dr =
            DrError::ElementInverted { step: 53, element: 1233, element_id: 1234, jacobian: -0.1 };
        let e = NewtonKrylovError::LoadNotCarried {
            reached: 0.905,
            load: 40.0,
            cause,
            fallback: Some(dr),
        };
        let text = e.to_string();
        assert!(text.contains("neither solver took the load past element 1233"), "{text}");
    }
}
