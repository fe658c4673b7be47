//! What every solver shares: the [`Solver`] trait that makes them interchangeable, the
//! progress record passed to observers, the common summary ([`Report`]) and error
//! ([`SolveError`]). Each solver also has its own parameters, info and error types
//! (`DrParams`/`DrInfo`/`DrError`, `NewtonParams`/`NewtonInfo`/`NewtonError`), returned by its
//! inherent `solve` and converted into the common ones by `From` behind the trait.

use std::time::Duration;

use bs_mesh::Vector3;

use crate::contact::{Contact, ContactReport};
use crate::data::{DataTerm, NoData};
use crate::loads::Loads;
use crate::model::Model;

/// Progress of one step (DR) or one iteration (Newton), passed to the observer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Step (DR) or cumulative iteration (Newton) number, from 1.
    pub step: usize,
    /// Current error estimate (DR: `max|Δu| ρₑ/(1−ρₑ)`; Newton: `max|δu|`), length units.
    /// DR reports `f64::INFINITY` during the ramp and the first snapshot window after it,
    /// before a convergence rate has been observed.
    pub err: f64,
    /// DR convergence rate ρ in use (Newton: 0).
    pub rho: f64,
    /// Load factor of the prescribed displacements (the 3-4-5 ramp value, or the load-step
    /// fraction for Newton), in `[0, 1]`.
    pub load_factor: f64,
    /// Largest nodal displacement magnitude.
    pub max_displacement: f64,
    /// What the contact handler did in this step.
    pub contact: ContactReport,
    /// Inner linear-solver iterations so far (Newton–Krylov; 0 for the others).
    pub linear_iterations: usize,
    /// Internal-force evaluations so far.
    pub force_evaluations: usize,
}

/// Where a solve spent its time (the parts a profile separates; the rest is vector
/// arithmetic and bookkeeping).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Breakdown {
    /// Internal-force evaluations.
    pub forces: Duration,
    /// Preconditioner applications (Newton–Krylov).
    pub preconditioner: Duration,
    /// Contact queries and enforcement.
    pub contact: Duration,
}

/// The common summary of a successful solve, what every solver can say (its own info type
/// says more: DR's convergence rate, Newton's load steps).
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Solver name, as scene files and reports spell it (`"newton-krylov"`, `"dr"`, `"newton"`).
    pub solver: &'static str,
    /// DR steps, or total Newton iterations.
    pub steps: usize,
    /// Final error estimate (length units).
    pub err: f64,
    /// The tolerance it was compared with (length units).
    pub tolerance: f64,
    /// Contact report of the last step (Newton–Krylov: nodes held on the surface at the end,
    /// and the largest penetration of any iterate).
    pub contact: ContactReport,
    /// Evaluations of the internal forces (DR: one per step; Newton–Krylov: residuals, line
    /// search trials and Jacobian products).
    pub force_evaluations: usize,
    /// Iterations of the inner linear solver (Newton–Krylov: GMRES; others: 0).
    pub linear_iterations: usize,
    /// Where the time went.
    pub breakdown: Breakdown,
    /// Wall-clock time of the solve.
    pub elapsed: Duration,
    /// How the load was carried (Newton–Krylov's continuation; `None` for the others).
    pub continuation: Option<ContinuationSummary>,
}

/// How a continuation carried the load to its end.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ContinuationSummary {
    /// Load levels converged (1: the whole load at once).
    pub load_levels: usize,
    /// Rebuilds of the preconditioner on the deformed configuration (Newton–Krylov).
    pub refreshes: usize,
    /// Failed attempts at a level retried with a smaller increment.
    pub cutbacks: usize,
    /// Dynamic Relaxation steps of the fallback (0: not needed).
    pub fallback_steps: usize,
}

/// Displacements and report of a successful solve: the common [`Report`] through the
/// [`Solver`] trait, or the solver's own info (`DrInfo`, `NewtonInfo`) from its inherent
/// `solve`.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution<R = Report> {
    /// Nodal displacements, indexed like the mesh nodes.
    pub displacements: Vec<Vector3<f64>>,
    /// Summary.
    pub report: R,
}

impl<R: Into<Report>> Solution<R> {
    /// The same solution with the common summary.
    pub fn into_common(self) -> Solution {
        Solution { displacements: self.displacements, report: self.report.into() }
    }
}

/// Why a solve stopped without an answer. Every variant names the cause and the fix.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// A solver parameter is out of range.
    #[error("invalid solver parameter {name} = {value}: {requirement}")]
    InvalidParams {
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// The loads were built for a different number of nodes.
    #[error(
        "loads are defined for {got} nodes but the model has {expected}: build Loads::new(model.node_count())"
    )]
    LoadMismatch {
        /// Model node count.
        expected: usize,
        /// Loads node count.
        got: usize,
    },
    /// A displacement became NaN or infinite.
    #[error(
        "non-finite displacement at step {step}: the solution blew up; reduce the time step \
         (step_fraction) or the load, and check the material parameters"
    )]
    NotFinite {
        /// Step at which it was detected.
        step: usize,
    },
    /// An element turned inside out.
    #[error(
        "element {element} (id {element_id}) inverted at step {step} (det F = {jacobian:e}): the \
         prescribed displacements are too large for this mesh (refine it or reduce the load), \
         or the time step is above critical (reduce step_fraction)"
    )]
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
    /// The iteration is unstable: the step-to-step change grows while alternating in sign,
    /// the signature of a time step above the critical one.
    #[error(
        "unstable iteration at step {step}: |Δu| grew by {growth:.2}x per step with alternating \
         sign for {steps} steps — the time step is above critical; reduce step_fraction (now \
         {step_fraction})"
    )]
    Unstable {
        /// Step at which it was detected.
        step: usize,
        /// Average growth factor of |Δu| per step over the detection window.
        growth: f64,
        /// Length of the detection window.
        steps: usize,
        /// The step fraction in use.
        step_fraction: f64,
    },
    /// Displacements grew far beyond the prescribed ones.
    #[error(
        "displacement grew without bound at step {step}: max |u| = {max_displacement:e} exceeds \
         {limit:e} (divergence_factor × load scale); reduce step_fraction or check the \
         constraints (an unconstrained rigid-body mode?)"
    )]
    Diverged {
        /// Step at which it was detected.
        step: usize,
        /// Largest displacement magnitude.
        max_displacement: f64,
        /// The bound it exceeded.
        limit: f64,
    },
    /// The step budget was exhausted.
    #[error(
        "no convergence within {steps} steps: error estimate {err:e} is above the tolerance \
         {tolerance:e}; raise max_steps, loosen the tolerance, or check for an unconstrained \
         (rigid-body) mode"
    )]
    NoConvergence {
        /// Error estimate reached.
        err: f64,
        /// Steps taken.
        steps: usize,
        /// The tolerance (length units).
        tolerance: f64,
    },
    /// The load continuation could not carry the prescribed displacements to their final
    /// values: it converged up to a fraction of them and says why it went no further, and
    /// what its fallback (Dynamic Relaxation from the last converged state) met, if it ran.
    #[error(
        "converged to {} of {} ({:.1} % of the load): {cause}{}",
        length(reached * load),
        length(*load),
        reached * 100.0,
        fallback_text(fallback)
    )]
    LoadNotCarried {
        /// Load fraction λ of the last converged level.
        reached: f64,
        /// The full load's size (the largest prescribed displacement component).
        load: f64,
        /// Why the next level failed.
        cause: LoadFailure,
        /// How the fallback from the last converged state stopped (`None`: not run).
        fallback: Option<Box<SolveError>>,
    },
    /// The tangent matrix could not be factorised.
    #[error(
        "tangent stiffness is singular or indefinite at load step {load_step}, iteration \
         {iteration}: the model has an unconstrained rigid-body mode or buckles; add fixed \
         nodes or use more load steps"
    )]
    SingularTangent {
        /// Load step (from 1).
        load_step: usize,
        /// Newton iteration within the load step (from 1).
        iteration: usize,
    },
    /// The preconditioner could not be built.
    #[error("the preconditioner could not be built: {reason}")]
    Preconditioner {
        /// Why.
        reason: String,
    },
    /// The solver does not support a feature of the model.
    #[error("{solver} does not support {what}: {fix}")]
    Unsupported {
        /// Solver name.
        solver: &'static str,
        /// The unsupported feature.
        what: &'static str,
        /// What to do instead.
        fix: &'static str,
    },
}

impl SolveError {
    /// A short stable name of the error kind (`"ElementInverted"`, `"NoConvergence"`, …), for
    /// tables and scripts.
    pub fn kind(&self) -> &'static str {
        match self {
            SolveError::InvalidParams { .. } => "InvalidParams",
            SolveError::LoadMismatch { .. } => "LoadMismatch",
            SolveError::NotFinite { .. } => "NotFinite",
            SolveError::ElementInverted { .. } => "ElementInverted",
            SolveError::Unstable { .. } => "Unstable",
            SolveError::Diverged { .. } => "Diverged",
            SolveError::NoConvergence { .. } => "NoConvergence",
            SolveError::SingularTangent { .. } => "SingularTangent",
            SolveError::LoadNotCarried { .. } => "LoadNotCarried",
            SolveError::Preconditioner { .. } => "Preconditioner",
            SolveError::Unsupported { .. } => "Unsupported",
        }
    }

    /// The step (DR) or iteration (Newton solvers) at which the solve stopped, when it got
    /// that far.
    pub fn step(&self) -> Option<usize> {
        match self {
            SolveError::NotFinite { step }
            | SolveError::ElementInverted { step, .. }
            | SolveError::Unstable { step, .. }
            | SolveError::Diverged { step, .. } => Some(*step),
            SolveError::NoConvergence { steps, .. } => Some(*steps),
            SolveError::SingularTangent { iteration, .. } => Some(*iteration),
            _ => None,
        }
    }
}

/// A length for a message: three decimals at most, trailing zeros dropped (36.2, 40).
fn length(x: f64) -> String {
    let s = format!("{x:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn fallback_text(fallback: &Option<Box<SolveError>>) -> String {
    match fallback.as_deref() {
        None => String::new(),
        Some(e @ SolveError::ElementInverted { element, element_id, .. }) => format!(
            "; Dynamic Relaxation from that state stopped too ({}): neither solver took the \
             load past element {element} (id {element_id}) — refine the mesh there, or reduce \
             the load",
            e.kind()
        ),
        Some(e) => format!("; Dynamic Relaxation from that state stopped too: {e}"),
    }
}

/// Why a load level could not be solved (the cause in [`SolveError::LoadNotCarried`]).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LoadFailure {
    /// Every step towards the next level was cut short by an element about to invert.
    #[error(
        "element {element} (id {element_id}) would invert under a larger load: the steps \
         that keep it valid make no progress"
    )]
    WouldInvert {
        /// Element index (mesh order).
        element: usize,
        /// External element id.
        element_id: u64,
    },
    /// The residual stopped decreasing.
    #[error("the residual stopped decreasing ({changes} contact nodes still changing state)")]
    Stalled {
        /// Contact nodes that changed state in the last iteration.
        changes: usize,
    },
    /// The level's iteration budget was spent while the residual still decreased.
    #[error("no convergence within {iterations} Newton iterations at the next load level")]
    Budget {
        /// Iterations spent.
        iterations: usize,
    },
    /// The whole solve's iteration budget was spent before the full load was carried.
    #[error("the solve's budget of {iterations} Newton iterations was spent")]
    Exhausted {
        /// The budget (Newton iterations over all levels).
        iterations: usize,
    },
}

/// Where a warm-started solve begins.
#[derive(Debug, Clone, Copy)]
pub struct WarmStart<'a> {
    /// A converged state of other prescribed values.
    pub state: &'a [Vector3<f64>],
    /// The converged state before `state` and the ratio `s` of the prescribed change now
    /// (from `state`'s values to the loads') to the change from its values to `state`'s,
    /// when the prescribed values continue along that line: Newton–Krylov then starts from
    /// the predictor `state + s (state − before)` (prescribed components at the loads'
    /// values, contact predicted, capped by the elements) instead of the linearised response.
    /// The other solvers use `state` alone.
    pub secant: Option<(&'a [Vector3<f64>], f64)>,
}

/// A watcher of the path: the progress and the displacements after a step.
pub type Watcher<'a> = dyn FnMut(&Progress, &[Vector3<f64>]) + 'a;

/// What a solve is asked, whichever solver answers: the model and its loads, where to
/// start, the contact and the measurements to honour, and who watches. The solver's own
/// parameters are the solver's (`DrParams`, `NewtonKrylovParams`, `NewtonParams`).
pub struct Problem<'a> {
    /// The discretised body.
    pub model: &'a Model,
    /// Prescribed displacements (their final values) and nodal forces.
    pub loads: &'a Loads,
    /// A converged state of other prescribed values to move from (`None`: the reference
    /// state). The prescribed components move from their values in it to the loads'.
    pub start: Option<WarmStart<'a>>,
    /// The kinematic contact, enforced after every step or iteration ([`NoContact`](crate::contact::NoContact)
    /// without a skull).
    pub contact: &'a mut dyn Contact,
    /// The measurements' energy added to the strain energy ([`NoData`] without).
    pub data: &'a mut dyn DataTerm,
    /// Called once per step (DR) or iteration (Newton–Krylov, Newton).
    pub observer: &'a mut dyn FnMut(&Progress),
    /// Also sees the displacements after each step (what a trace of the path records);
    /// Dynamic Relaxation calls it, the Newton solvers do not.
    pub watch: Option<&'a mut Watcher<'a>>,
}

impl std::fmt::Debug for Problem<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Problem")
            .field("nodes", &self.model.node_count())
            .field("start", &self.start.map(|w| w.secant.is_some()))
            .field("data", &self.data.is_active())
            .field("watch", &self.watch.is_some())
            .finish_non_exhaustive()
    }
}

impl<'a> Problem<'a> {
    /// `model` under `loads` from the reference state, with `contact` and `observer`, no
    /// measurements and no watcher.
    pub fn new(
        model: &'a Model,
        loads: &'a Loads,
        contact: &'a mut dyn Contact,
        observer: &'a mut dyn FnMut(&Progress),
    ) -> Self {
        // `NoData` is zero-sized: leaking a box of it allocates and leaks nothing.
        let data: &'a mut NoData = Box::leak(Box::new(NoData));
        Problem { model, loads, start: None, contact, data, observer, watch: None }
    }

    /// The same problem started from `state` (no secant).
    pub fn from_state(self, state: &'a [Vector3<f64>]) -> Self {
        Problem { start: Some(WarmStart { state, secant: None }), ..self }
    }

    /// The same problem with the measurements `data`.
    pub fn with_data(self, data: &'a mut dyn DataTerm) -> Self {
        Problem { data, ..self }
    }
}

/// A static solver: Dynamic Relaxation, Newton–Krylov and Newton are interchangeable
/// behind this trait (each also has an inherent `solve` of the same [`Problem`] returning
/// its own info and error).
pub trait Solver {
    /// Solver name, as scene files and reports spell it.
    fn name(&self) -> &'static str;

    /// Solves `problem` for the equilibrium displacements of its model under its loads
    /// (prescribed displacements reach their final values, zero traction elsewhere).
    fn solve(&self, problem: Problem<'_>) -> Result<Solution, SolveError>;
}

/// A solver parameter out of range: every solver's error has a variant for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct InvalidParam {
    pub name: &'static str,
    pub value: f64,
    pub requirement: &'static str,
}

impl From<InvalidParam> for SolveError {
    fn from(p: InvalidParam) -> Self {
        SolveError::InvalidParams { name: p.name, value: p.value, requirement: p.requirement }
    }
}

/// `Ok` if `ok` and `value` is finite, else the parameter `name` with what it must satisfy.
pub(crate) fn param(
    name: &'static str,
    value: f64,
    ok: bool,
    requirement: &'static str,
) -> Result<(), InvalidParam> {
    if ok && value.is_finite() { Ok(()) } else { Err(InvalidParam { name, value, requirement }) }
}

/// What a solver's `tolerance` is measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ToleranceUnit {
    /// A fraction of the problem's [`load_scale`] (the default: a tolerance that means the
    /// same for any push).
    #[default]
    LoadScale,
    /// The mesh's length unit (a scene file's `[solver] tolerance`).
    Length,
}

impl ToleranceUnit {
    /// `tolerance` in the mesh's length unit, for a problem of load scale `load_scale`.
    pub fn length(self, tolerance: f64, load_scale: f64) -> f64 {
        match self {
            ToleranceUnit::LoadScale => tolerance * load_scale,
            ToleranceUnit::Length => tolerance,
        }
    }
}

/// Length scale of a problem: the largest prescribed displacement component, or the
/// bounding-box diagonal when nothing moves. Tolerances in [`ToleranceUnit::LoadScale`] and
/// the divergence limits are relative to it.
pub fn load_scale(model: &Model, loads: &Loads) -> f64 {
    let m = loads.max_prescribed();
    if m > 0.0 { m } else { model.diagonal().max(f64::MIN_POSITIVE) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A load-scale tolerance is a fraction of the push; a length tolerance is itself.
    #[test]
    fn a_tolerance_is_a_length_in_either_unit() {
        assert_eq!(ToleranceUnit::LoadScale.length(1e-6, 8.0), 8e-6);
        assert_eq!(ToleranceUnit::Length.length(1e-3, 8.0), 1e-3);
        assert_eq!(ToleranceUnit::default(), ToleranceUnit::LoadScale);
    }
}
