//! What a Dynamic Relaxation solve returns: [`DrInfo`] on success, [`DrError`] otherwise,
//! each converting into the common [`Report`] and [`SolveError`] of the `Solver` trait.

use std::fmt;
use std::time::Duration;

use crate::assembly::Inversion;
use crate::contact::ContactReport;
use crate::solver::{InvalidParam, Report, SolveError};

/// What a converged Dynamic Relaxation solve did.
#[derive(Debug, Clone, PartialEq)]
pub struct DrInfo {
    /// Steps taken (one force evaluation each).
    pub steps: usize,
    /// Final error estimate `max|Δu| ρₑ/(1 − ρₑ)` (length units).
    pub err: f64,
    /// The tolerance it was compared with (length units).
    pub tolerance: f64,
    /// Final convergence rate ρ.
    pub rho: f64,
    /// Final lowest-eigenvalue estimate `ω_min` of `M⁻¹K`, in units of 1/h.
    pub omega_min: f64,
    /// What the contact handler did in the last step.
    pub contact: ContactReport,
    /// Wall-clock time of the solve.
    pub elapsed: Duration,
}

impl From<DrInfo> for Report {
    fn from(i: DrInfo) -> Report {
        Report {
            solver: "dr",
            steps: i.steps,
            err: i.err,
            tolerance: i.tolerance,
            contact: i.contact,
            force_evaluations: i.steps,
            linear_iterations: 0,
            breakdown: Default::default(),
            elapsed: i.elapsed,
            continuation: None,
        }
    }
}

/// Why a Dynamic Relaxation solve stopped without an answer. The messages are those of the
/// matching [`SolveError`] variants (each names the cause and the fix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DrError {
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
    /// A displacement became NaN or infinite.
    NotFinite {
        /// Step at which it was detected.
        step: usize,
    },
    /// An element turned inside out.
    ElementInverted {
        /// Step at which it was detected.
        step: usize,
        /// Element index (mesh order).
        element: usize,
        /// External element id.
        element_id: u64,
        /// The offending `det F` (or `J̄` for T4ANP).
        jacobian: f64,
    },
    /// `Δu` grew while alternating in sign: the time step is above critical.
    Unstable {
        /// Step at which it was detected.
        step: usize,
        /// Average growth factor of `|Δu|` per step over the detection window.
        growth: f64,
        /// Length of the detection window.
        steps: usize,
        /// The step fraction in use.
        step_fraction: f64,
    },
    /// Displacements grew far beyond the prescribed ones.
    Diverged {
        /// Step at which it was detected.
        step: usize,
        /// Largest displacement magnitude.
        max_displacement: f64,
        /// The bound it exceeded.
        limit: f64,
    },
    /// The step budget was exhausted.
    NoConvergence {
        /// Error estimate reached.
        err: f64,
        /// Steps taken.
        steps: usize,
        /// The tolerance (length units).
        tolerance: f64,
    },
}

impl DrError {
    /// The inversion found at `step`.
    pub(crate) fn inverted(step: usize, inv: Inversion) -> DrError {
        let Inversion { element, element_id, jacobian } = inv;
        DrError::ElementInverted { step, element, element_id, jacobian }
    }

    /// A short stable name of the error kind (that of the matching [`SolveError`]).
    pub fn kind(&self) -> &'static str {
        SolveError::from(*self).kind()
    }
}

impl From<InvalidParam> for DrError {
    fn from(p: InvalidParam) -> Self {
        DrError::InvalidParams { name: p.name, value: p.value, requirement: p.requirement }
    }
}

impl From<DrError> for SolveError {
    fn from(e: DrError) -> SolveError {
        match e {
            DrError::InvalidParams { name, value, requirement } => {
                SolveError::InvalidParams { name, value, requirement }
            }
            DrError::LoadMismatch { expected, got } => SolveError::LoadMismatch { expected, got },
            DrError::NotFinite { step } => SolveError::NotFinite { step },
            DrError::ElementInverted { step, element, element_id, jacobian } => {
                SolveError::ElementInverted { step, element, element_id, jacobian }
            }
            DrError::Unstable { step, growth, steps, step_fraction } => {
                SolveError::Unstable { step, growth, steps, step_fraction }
            }
            DrError::Diverged { step, max_displacement, limit } => {
                SolveError::Diverged { step, max_displacement, limit }
            }
            DrError::NoConvergence { err, steps, tolerance } => {
                SolveError::NoConvergence { err, steps, tolerance }
            }
        }
    }
}

impl fmt::Display for DrError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        SolveError::from(*self).fmt(f)
    }
}

impl std::error::Error for DrError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_keep_the_common_message_and_kind() {
        let e = DrError::Unstable { step: 7, growth: 1.5, steps: 4, step_fraction: 1.2 };
        let common = SolveError::from(e);
        assert_eq!(e.to_string(), common.to_string());
        assert_eq!((e.kind(), common.step()), ("Unstable", Some(7)));
        assert!(e.to_string().contains("reduce step_fraction (now 1.2)"), "{e}");
    }

    #[test]
    fn info_becomes_the_common_report() {
        let info = DrInfo {
            steps: 12,
            err: 1e-7,
            tolerance: 1e-6,
            rho: 0.99,
            omega_min: 0.01,
            contact: ContactReport::default(),
            elapsed: Duration::from_millis(3),
        };
        let r = Report::from(info);
        assert_eq!(
            (r.solver, r.steps, r.force_evaluations, r.linear_iterations),
            ("dr", 12, 12, 0)
        );
        assert_eq!((r.err, r.tolerance), (1e-7, 1e-6));
    }
}
