//! Static Newton–Raphson reference solver: load stepping, backtracking line search, sparse
//! tangent stiffness assembled on the free DOFs and factorised with faer's sparse Cholesky
//! (symbolic factorisation computed once and reused).
//!
//! Supported elements: T4 and H8 (mean strain + hourglass stiffness). T4ANP's nodal
//! averaging couples neighbouring elements in the tangent and is not supported (use DR).
//! Contact is not supported: after convergence the contact handler is called once, and if it
//! reports nodes in contact the solve fails with [`NewtonError::Unsupported`].
//!
//! Parts: [`params`], [`system`] (the free-DOF tangent system and its factorisation) and
//! [`outcome`] ([`NewtonInfo`], [`NewtonError`] and their conversion to the common types).

pub mod outcome;
pub mod params;
pub(crate) mod system;

use std::time::Instant;

use bs_mesh::{Point3, Vector3};

pub use outcome::{NewtonError, NewtonInfo};
pub use params::NewtonParams;

use self::system::TangentSystem;
use crate::assembly::Workspace;
use crate::contact::{Contact, ContactReport};
use crate::model::Model;
use crate::solver::{Problem, Progress, Solution, SolveError, Solver, load_scale};

/// The static Newton–Raphson solver.
#[derive(Debug, Clone, Copy, Default)]
pub struct Newton {
    /// Parameters.
    pub params: NewtonParams,
}

/// The iterate, a trial state and their scratch.
struct State {
    u: Vec<Vector3<f64>>,
    trial: Vec<Vector3<f64>>,
    forces: Vec<Vector3<f64>>,
    ws: Workspace,
    /// Internal-force evaluations so far.
    evaluations: usize,
    /// The dead nodal forces (empty: none) and the load fraction they act at.
    dead: Vec<Vector3<f64>>,
    load_factor: f64,
}

impl State {
    /// Forces at `trial` and their free-DOF norm (`None` if an element inverts).
    fn trial_norm(&mut self, model: &Model, sys: &TangentSystem) -> Option<f64> {
        self.evaluations += 1;
        let r = model.internal_forces_into(&self.trial, &mut self.ws, &mut self.forces);
        self.subtract_dead();
        r.ok().map(|()| sys.residual_norm(&self.forces))
    }

    /// `forces ← forces − λ f_ext`.
    fn subtract_dead(&mut self) {
        let l = self.load_factor;
        self.forces.iter_mut().zip(&self.dead).for_each(|(f, e)| *f -= e * l);
    }

    /// `trial = u` (+ `α δ`) (+ the increment `dp` of the prescribed DOFs).
    fn set_trial(&mut self, sys: &TangentSystem, alpha: Option<f64>, dp: Option<&[f64]>) {
        self.trial.copy_from_slice(&self.u);
        if let Some(alpha) = alpha {
            for (i, &d) in sys.free.iter().enumerate() {
                self.trial[d / 3][d % 3] += alpha * sys.rhs[(i, 0)];
            }
        }
        if let Some(dp) = dp {
            for &d in &sys.fixed {
                self.trial[d / 3][d % 3] += dp[d];
            }
        }
    }

    /// Backtracking on the free-DOF residual norm, compared with that of the state with only
    /// the prescribed increment applied: the accepted step is left in `trial`; `false` if
    /// twelve halvings found none.
    fn line_search(
        &mut self,
        model: &Model,
        sys: &TangentSystem,
        dp: Option<&[f64]>,
        on: bool,
    ) -> bool {
        let ref_norm = if on {
            self.set_trial(sys, None, dp);
            self.trial_norm(model, sys).unwrap_or(f64::INFINITY)
        } else {
            f64::INFINITY
        };
        let mut alpha = 1.0;
        for _ in 0..12 {
            self.set_trial(sys, Some(alpha), dp);
            if !on {
                return true;
            }
            if let Some(rn) = self.trial_norm(model, sys)
                && (rn <= ref_norm * (1.0 + 1e-9) || alpha < 1e-3)
            {
                return true;
            }
            alpha *= 0.5;
        }
        false
    }
}

impl Newton {
    /// A solver with the given parameters.
    pub fn new(params: NewtonParams) -> Self {
        Newton { params }
    }

    /// Solves `problem` from the reference state in equal load steps; its contact is only
    /// checked on the answer, its observer called once per iteration. A start state or
    /// active measurements are refused ([`NewtonError::Unsupported`]): this is the
    /// reference solver of the plain elastic problem.
    pub fn solve(&self, problem: Problem<'_>) -> Result<Solution<NewtonInfo>, NewtonError> {
        let Problem { model, loads, start, contact, data, observer, watch: _ } = problem;
        if start.is_some() {
            return Err(NewtonError::Unsupported {
                what: "a warm start from a previous state",
                fix: "use kind = \"newton-krylov\" or \"dr\" for updates",
            });
        }
        if data.is_active() {
            return Err(NewtonError::Unsupported {
                what: "measurements",
                fix: "use kind = \"newton-krylov\" or \"dr\" to fit measurements",
            });
        }
        let p = self.params;
        p.validate()?;
        let n = model.node_count();
        if loads.node_count() != n {
            return Err(NewtonError::LoadMismatch { expected: n, got: loads.node_count() });
        }
        if model.elements.anp() {
            return Err(NewtonError::Unsupported {
                what: "T4ANP tetrahedra",
                fix: "use TetFormulation::T4 or the Dynamic Relaxation solver",
            });
        }
        let start = Instant::now();
        let tol = p.tolerance_unit.length(p.tolerance, load_scale(model, loads));
        let mut sys = TangentSystem::new(model, loads)?;
        let zero = vec![Vector3::<f64>::zeros(); n];
        let mut s = State {
            u: zero.clone(),
            trial: zero.clone(),
            forces: zero,
            ws: model.workspace(),
            evaluations: 0,
            dead: loads.forces().to_vec(),
            load_factor: 0.0,
        };
        let mut dp = vec![0.0; 3 * n];
        let (mut iterations, mut last_err) = (0usize, f64::INFINITY);
        for ls in 1..=p.load_steps {
            let lf = ls as f64 / p.load_steps as f64;
            let lf_prev = (ls - 1) as f64 / p.load_steps as f64;
            dp.iter_mut().for_each(|v| *v = 0.0);
            for &d in &sys.fixed {
                dp[d] = loads.value(d / 3, d % 3) * (lf - lf_prev);
            }
            let mut converged = false;
            for it in 1..=p.max_iterations {
                iterations += 1;
                // The increment of the prescribed DOFs goes in with the first iteration.
                let inc = (it == 1).then_some(dp.as_slice());
                s.evaluations += 1;
                if let Err(inv) = model.internal_forces_into(&s.u, &mut s.ws, &mut s.forces) {
                    return Err(NewtonError::inverted(iterations, inv));
                }
                s.load_factor = lf;
                s.subtract_dead();
                sys.correction(model, &s.u, &s.forces, inc, (ls, it))?;
                if !s.line_search(model, &sys, inc, p.line_search) {
                    let (err, steps) = (last_err, iterations);
                    return Err(NewtonError::NoConvergence { err, steps, tolerance: tol });
                }
                std::mem::swap(&mut s.u, &mut s.trial);
                // The full correction (before the line-search scaling) measures convergence.
                let step_max = sys.max_correction();
                last_err = step_max;
                let maxu = s.u.iter().fold(0.0f64, |a, v| a.max(v.norm()));
                observer(&Progress {
                    step: iterations,
                    err: step_max,
                    rho: 0.0,
                    load_factor: lf,
                    max_displacement: maxu,
                    contact: Default::default(),
                    linear_iterations: 0,
                    force_evaluations: s.evaluations,
                });
                if !step_max.is_finite() {
                    return Err(NewtonError::NotFinite { step: iterations });
                }
                if it > 1 && step_max <= tol {
                    converged = true;
                    break;
                }
            }
            if !converged {
                let (err, steps) = (last_err, iterations);
                return Err(NewtonError::NoConvergence { err, steps, tolerance: tol });
            }
        }
        let report = Self::contact_check(model, &s.u, contact)?;
        let info = NewtonInfo {
            iterations,
            load_steps: p.load_steps,
            err: last_err,
            tolerance: tol,
            force_evaluations: s.evaluations,
            contact: report,
            elapsed: start.elapsed(),
        };
        Ok(Solution { displacements: s.u, report: info })
    }

    /// Contact is not supported: the answer must not penetrate the contact surface.
    fn contact_check(
        model: &Model,
        u: &[Vector3<f64>],
        contact: &mut dyn Contact,
    ) -> Result<ContactReport, NewtonError> {
        let mut positions: Vec<Point3<f64>> =
            model.reference().iter().zip(u).map(|(x, d)| x + d).collect();
        let report = contact.enforce(&mut positions);
        if report.nodes_in_contact > 0 {
            return Err(NewtonError::Unsupported {
                what: "contact (the converged state penetrates the contact surface)",
                fix: "use the Dynamic Relaxation solver for contact problems",
            });
        }
        Ok(report)
    }
}

impl Solver for Newton {
    fn name(&self) -> &'static str {
        "newton"
    }

    fn solve(&self, problem: Problem<'_>) -> Result<Solution, SolveError> {
        Ok(Newton::solve(self, problem)?.into_common())
    }
}
