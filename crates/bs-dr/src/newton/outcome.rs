//! What a Newton–Raphson solve returns: [`NewtonInfo`] on success, [`NewtonError`]
//! otherwise, each converting into the common [`Report`] and [`SolveError`].

use std::fmt;
use std::time::Duration;

use crate::assembly::Inversion;
use crate::contact::ContactReport;
use crate::solver::{InvalidParam, Report, SolveError};

/// What a converged Newton–Raphson solve did.
#[derive(Debug, Clone, PartialEq)]
pub struct NewtonInfo {
    /// Newton iterations over all load steps.
    pub iterations: usize,
    /// Load steps.
    pub load_steps: usize,
    /// The last full Newton correction `max|δu|` (length units).
    pub err: f64,
    /// The tolerance it was compared with (length units).
    pub tolerance: f64,
    /// Internal-force evaluations (residuals and line-search trials).
    pub force_evaluations: usize,
    /// The contact check of the answer (no node in contact, or the solve fails).
    pub contact: ContactReport,
    /// Wall-clock time of the solve.
    pub elapsed: Duration,
}

impl From<NewtonInfo> for Report {
    fn from(i: NewtonInfo) -> Report {
        Report {
            solver: "newton",
            steps: i.iterations,
            err: i.err,
            tolerance: i.tolerance,
            contact: i.contact,
            force_evaluations: i.force_evaluations,
            linear_iterations: 0,
            breakdown: Default::default(),
            elapsed: i.elapsed,
            continuation: None,
        }
    }
}

/// Why a Newton–Raphson solve stopped without an answer. The messages are those of the
/// matching [`SolveError`] variants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NewtonError {
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
    /// The model or the answer needs what the reference does not do.
    Unsupported {
        /// The unsupported feature.
        what: &'static str,
        /// What to do instead.
        fix: &'static str,
    },
    /// The tangent could not be factorised.
    SingularTangent {
        /// Load step (from 1; 0 for the symbolic factorisation).
        load_step: usize,
        /// Iteration within the load step (from 1).
        iteration: usize,
    },
    /// An element turned inside out.
    ElementInverted {
        /// Iteration at which it was detected.
        step: usize,
        /// Element index (mesh order).
        element: usize,
        /// External element id.
        element_id: u64,
        /// Its `det F`.
        jacobian: f64,
    },
    /// No step decreased the residual, or a load step ran out of iterations.
    NoConvergence {
        /// The last correction.
        err: f64,
        /// Iterations taken.
        steps: usize,
        /// The tolerance (length units).
        tolerance: f64,
    },
    /// A correction became NaN or infinite.
    NotFinite {
        /// Iteration at which it was detected.
        step: usize,
    },
}

impl NewtonError {
    /// The inversion found at iteration `step`.
    pub(crate) fn inverted(step: usize, inv: Inversion) -> NewtonError {
        let Inversion { element, element_id, jacobian } = inv;
        NewtonError::ElementInverted { step, element, element_id, jacobian }
    }

    /// A short stable name of the error kind (that of the matching [`SolveError`]).
    pub fn kind(&self) -> &'static str {
        SolveError::from(*self).kind()
    }
}

impl From<InvalidParam> for NewtonError {
    fn from(p: InvalidParam) -> Self {
        NewtonError::InvalidParams { name: p.name, value: p.value, requirement: p.requirement }
    }
}

impl From<NewtonError> for SolveError {
    fn from(e: NewtonError) -> SolveError {
        match e {
            NewtonError::InvalidParams { name, value, requirement } => {
                SolveError::InvalidParams { name, value, requirement }
            }
            NewtonError::LoadMismatch { expected, got } => {
                SolveError::LoadMismatch { expected, got }
            }
            NewtonError::Unsupported { what, fix } => {
                SolveError::Unsupported { solver: "newton", what, fix }
            }
            NewtonError::SingularTangent { load_step, iteration } => {
                SolveError::SingularTangent { load_step, iteration }
            }
            NewtonError::ElementInverted { step, element, element_id, jacobian } => {
                SolveError::ElementInverted { step, element, element_id, jacobian }
            }
            NewtonError::NoConvergence { err, steps, tolerance } => {
                SolveError::NoConvergence { err, steps, tolerance }
            }
            NewtonError::NotFinite { step } => SolveError::NotFinite { step },
        }
    }
}

impl fmt::Display for NewtonError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        SolveError::from(*self).fmt(f)
    }
}

impl std::error::Error for NewtonError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_keep_the_common_message_and_kind() {
        let e = NewtonError::Unsupported { what: "T4ANP tetrahedra", fix: "use T4" };
        assert_eq!(e.to_string(), "newton does not support T4ANP tetrahedra: use T4");
        assert_eq!(e.kind(), "Unsupported");
        let s = NewtonError::SingularTangent { load_step: 2, iteration: 3 };
        assert_eq!(SolveError::from(s).step(), Some(3));
    }

    #[test]
    fn info_becomes_the_common_report() {
        let info = NewtonInfo {
            iterations: 9,
            load_steps: 3,
            err: 1e-12,
            tolerance: 1e-10,
            force_evaluations: 30,
            contact: ContactReport::default(),
            elapsed: Duration::ZERO,
        };
        let r = Report::from(info);
        assert_eq!((r.solver, r.steps, r.force_evaluations), ("newton", 9, 30));
    }
}
