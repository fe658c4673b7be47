//! Adaptive Dynamic Relaxation (the explicit steady-state solver).
//!
//! The iteration (Joldes, Wittek & Miller's adaptive DR, a second-order Richardson
//! iteration with mass-proportional damping), with pseudo time step `h = 1`:
//!
//! `u⁺ = u + ρ² (u − u⁻) + ((1+ρ) h / 2)² M⁻¹ (f_ext − f_int(u))`, `f_ext` the dead nodal
//! forces of the [`Loads`] (a body force; zero traction elsewhere).
//!
//! * Masses are fictitious ([`Model::dr_masses_into`]): element `e` gets the mass that makes
//!   its own critical step `h / step_fraction`, so every node has the same stable step (from
//!   a deformed start state, the stiffer of each element's reference and current shapes:
//!   [`Model::dr_masses_at_into`]). As elements flatten or shear their critical steps
//!   shrink: every ten steps, once a node has moved a tenth of the smallest element length
//!   since the last time, a node whose mass no longer covers its hexahedra's current shapes
//!   at the critical step is raised to what they need at the step fraction
//!   ([`Model::dr_masses_stiffened_into`]; never lowered; tetrahedra keep their masses).
//!   Without this the paper's 40 mm push of a hexahedral ellipsoid turns unstable or
//!   inverts an element during the ramp.
//! * The convergence rate `ρ = (κ − 1)/(κ + 1)`, `κ = 2/(ω_min h)`, comes from a
//!   Rayleigh-quotient estimate of the lowest eigenvalue of `M⁻¹K` taken from snapshots every
//!   `snapshot_interval` steps after the ramp: `ω²_min ≈ |Δuᵀ Δf| / (Δuᵀ M Δu)` over free
//!   DOFs. A new ρ is accepted once two successive estimates agree within 10%. Before that a
//!   geometric guess is used (quarter-wave of the fictitious shear wave over the bounding-box
//!   diagonal).
//! * Termination: `err = max|Δu| ρₑ/(1 − ρₑ) < tolerance × load scale` for `consecutive`
//!   steps in a row, never a fixed step count. `ρₑ` is the more pessimistic of the rate from
//!   `0.9 ω_min` and the decay rate of `max|Δu|` observed over the last snapshot window.
//! * Prescribed components follow the 3-4-5 ramp over `ramp_steps` steps, then stay; so do
//!   the dead forces from rest (from a start state they act in full from the first step).
//! * Measurements ([`DataTerm`]) are an external force: the springs of their linearisation,
//!   ramped in with the prescribed components and linearised again every
//!   `snapshot_interval` steps; each node's mass also carries its springs' stiffness bound
//!   (never decreasing), so the step stays stable.
//! * Guard: non-finite values, an inverted element, alternating growth of `Δu` (time step
//!   above critical) and displacements beyond `divergence_factor × load scale` stop the run
//!   with a typed [`DrError`].
//!
//! The loop below calls named parts: [`params`] (ranges), [`rayleigh`] (the estimator of ρ
//! and of the error), [`guard`] (what stops a run that cannot converge) and [`outcome`]
//! ([`DrInfo`], [`DrError`] and their conversion to the common types).

pub mod guard;
pub mod outcome;
pub mod params;
pub mod rayleigh;

use std::time::Instant;

use bs_mesh::{Point3, Vector3};

pub use outcome::{DrError, DrInfo};
pub use params::DrParams;

use self::guard::{GrowthGuard, StepChange};
use self::rayleigh::RayleighEstimator;
use crate::assembly::Workspace;
use crate::contact::{Contact, ContactReport};
use crate::data::{DataTerm, Springs};
use crate::loads::{Loads, ramp};
use crate::model::Model;
use crate::solver::{Problem, Progress, Solution, SolveError, Solver, load_scale};

/// Steps between checks whether the element masses need refreshing at the current shapes.
const REFRESH_INTERVAL: usize = 10;

/// The masses are refreshed once some node has moved this fraction of the smallest element
/// length (`min_e V_e^(1/3)`) since the last refresh: an element's stiffness bound grows at
/// most about `1/(1 − 0.1)² ≈ 1.23×` in between, inside the `1/0.8² ≈ 1.56×` margin of the
/// default step fraction.
const REFRESH_MOVE: f64 = 0.1;

/// How much an element's stiffness bound may grow between refreshes (`1/(1 − 0.1)²`
/// rounded up): a node is raised once its mass would not cover that growth at the critical
/// step.
const REFRESH_GROWTH: f64 = 1.25;

/// The adaptive Dynamic Relaxation solver.
#[derive(Debug, Clone, Copy, Default)]
pub struct DynamicRelaxation {
    /// Parameters.
    pub params: DrParams,
}

/// What the loop reads: masses, which DOFs are free and fixed, and the fixed values.
struct Setup {
    /// The masses the elements alone need, and the masses in use (with the springs').
    element_masses: Vec<f64>,
    masses: Vec<f64>,
    inv_m: Vec<f64>,
    free: Vec<usize>,
    fixed: Vec<usize>,
    /// Start and final values of the constrained DOFs (the ramp goes from one to the other).
    fixed_start: Vec<f64>,
    fixed_value: Vec<f64>,
    /// `min_e V_e^(1/3)`, the length that schedules the mass refreshes.
    smallest_length: f64,
}

impl Setup {
    fn new(model: &Model, loads: &Loads, step_fraction: f64, start: &[Vector3<f64>]) -> Self {
        let mut masses = vec![0.0; model.node_count()];
        model.dr_masses_at_into(step_fraction, start, &mut masses);
        let inv_m = masses.iter().map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 }).collect();
        let (free, fixed) = loads.split_dofs();
        let fixed_value = fixed.iter().map(|&d| loads.value(d / 3, d % 3)).collect();
        let fixed_start = fixed.iter().map(|&d| start[d / 3][d % 3]).collect();
        let element_masses = masses.clone();
        let smallest_length = model.smallest_element_length();
        Setup {
            element_masses,
            masses,
            inv_m,
            free,
            fixed,
            fixed_start,
            fixed_value,
            smallest_length,
        }
    }

    /// The measurements linearised at `u` into `springs`, and the masses raised where the
    /// springs' stiffness needs it (`m_a ≥ m_elements + k_a / 4f²`; never lowered).
    fn linearise(
        &mut self,
        model: &Model,
        s: &mut State,
        step_fraction: f64,
        data: &mut dyn DataTerm,
    ) {
        let reference = model.reference();
        for (x, (x0, u)) in s.positions.iter_mut().zip(reference.iter().zip(&s.u)) {
            *x = x0 + u;
        }
        data.linearise(&s.positions, &mut s.springs);
        s.bound.iter_mut().for_each(|b| *b = 0.0);
        s.springs.add_stiffness_bound_into(&mut s.bound);
        let f2 = step_fraction * step_fraction;
        for (a, &k) in s.bound.iter().enumerate() {
            let m = self.element_masses[a] + k / (4.0 * f2);
            if m > self.masses[a] {
                self.masses[a] = m;
                self.inv_m[a] = 1.0 / m;
            }
        }
    }

    /// The element masses raised where the elements' shapes at `s.u` need more (a
    /// flattened or sheared element's critical step is shorter than its reference one),
    /// once a node has moved [`REFRESH_MOVE`] of the smallest element length since the last
    /// refresh. A node is raised only once its mass would not cover the current shapes'
    /// need at the critical step itself (step fraction 1) grown by [`REFRESH_GROWTH`], and
    /// then to what they need at the run's step fraction: heavier nodes slow the iteration
    /// (the hexahedral 40 mm ellipsoid: 3761 steps, 3988 with every stiffened node raised),
    /// so masses grow only where the step would otherwise turn unstable before the next
    /// refresh. Never lowered; the measurements' share kept.
    fn refresh(&mut self, model: &Model, s: &mut State, step_fraction: f64) {
        if model.elements.hexes.is_empty() {
            return; // only hexahedra's masses are refreshed (see `dr_masses_stiffened_into`)
        }
        let moved = s.u.iter().zip(&s.refreshed).map(|(a, b)| (a - b).norm_squared());
        if moved.fold(0.0, f64::max).sqrt() < REFRESH_MOVE * self.smallest_length {
            return;
        }
        s.refreshed.copy_from_slice(&s.u);
        model.dr_masses_stiffened_into(step_fraction, &s.u, &mut s.fresh);
        let at_risk = REFRESH_GROWTH * step_fraction * step_fraction;
        for (a, &m) in s.fresh.iter().enumerate() {
            if m * at_risk > self.element_masses[a] {
                self.masses[a] += m - self.element_masses[a];
                self.element_masses[a] = m;
                self.inv_m[a] = 1.0 / self.masses[a];
            }
        }
    }

    /// `u⁺ = u + ρ²(u − u⁻) − ¼(1 + ρ)² M⁻¹ f` on the free DOFs; the fixed ones at `load`
    /// of the way from their start to their final values.
    fn step(&self, s: &mut State, rho: f64, load: f64) {
        let beta = 0.25 * (1.0 + rho) * (1.0 + rho);
        let r2 = rho * rho;
        let (u, u_prev, f) = (&s.u, &s.u_prev, &s.f);
        for &d in &self.free {
            let (a, c) = (d / 3, d % 3);
            s.u_next[a][c] =
                u[a][c] + r2 * (u[a][c] - u_prev[a][c]) - beta * f[a][c] * self.inv_m[a];
        }
        for (i, &d) in self.fixed.iter().enumerate() {
            let (a, b) = (self.fixed_start[i], self.fixed_value[i]);
            s.u_next[d / 3][d % 3] = a + (b - a) * load;
        }
    }
}

/// The iterates and scratch of one solve, allocated before the loop.
struct State {
    u: Vec<Vector3<f64>>,
    u_prev: Vec<Vector3<f64>>,
    u_next: Vec<Vector3<f64>>,
    f: Vec<Vector3<f64>>,
    positions: Vec<Point3<f64>>,
    ws: Workspace,
    /// The measurements' springs and their per-node stiffness bounds.
    springs: Springs,
    bound: Vec<f64>,
    /// The element masses at the current shapes (scratch of [`Setup::refresh`]) and the
    /// displacements they were last computed at.
    fresh: Vec<f64>,
    refreshed: Vec<Vector3<f64>>,
}

impl State {
    fn new(model: &Model, start: &[Vector3<f64>]) -> Self {
        let zero = vec![Vector3::<f64>::zeros(); model.node_count()];
        State {
            u: start.to_vec(),
            u_prev: start.to_vec(),
            u_next: start.to_vec(),
            f: zero,
            positions: model.reference().to_vec(),
            ws: model.workspace(),
            springs: Springs::new(),
            bound: vec![0.0; model.node_count()],
            fresh: vec![0.0; model.node_count()],
            refreshed: start.to_vec(),
        }
    }

    /// The kinematic contact on `u_next`: nodes the handler moved take its position in the
    /// components that are not prescribed.
    fn contact(
        &mut self,
        model: &Model,
        loads: &Loads,
        contact: &mut dyn Contact,
    ) -> ContactReport {
        let reference = model.reference();
        for (x, (x0, un)) in self.positions.iter_mut().zip(reference.iter().zip(&self.u_next)) {
            *x = x0 + un;
        }
        let report = contact.enforce(&mut self.positions);
        for a in 0..reference.len() {
            let x = self.positions[a];
            if x != reference[a] + self.u_next[a] {
                let moved = x - reference[a];
                for c in 0..3 {
                    if !loads.is_constrained(a, c) {
                        self.u_next[a][c] = moved[c];
                    }
                }
            }
        }
        report
    }

    /// `u⁻ ← u ← u⁺`.
    fn advance(&mut self) {
        std::mem::swap(&mut self.u_prev, &mut self.u);
        std::mem::swap(&mut self.u, &mut self.u_next);
    }
}

impl DynamicRelaxation {
    /// A solver with the given parameters.
    pub fn new(params: DrParams) -> Self {
        DynamicRelaxation { params }
    }

    /// Geometric first guess of `ω_min` (units of 1/h): a quarter shear wave across the
    /// bounding-box diagonal with the fictitious density.
    fn omega_guess(model: &Model, masses: &[f64]) -> f64 {
        let (vol, mu_vol) = model.volume_and_shear();
        let mass: f64 = masses.iter().sum();
        let diag = model.diagonal();
        let c = (mu_vol / vol / (mass / vol)).sqrt();
        std::f64::consts::FRAC_PI_2 * c / diag
    }

    /// Solves `problem`: its prescribed components ramp from their values in its start state
    /// (zero without one) to the loads', the kinematic contact is enforced after every step
    /// and the measurements' energy is an external force (see [`crate::data`]); the
    /// observer is called once per step, the watcher (if any) with the displacements too.
    pub fn solve(&self, problem: Problem<'_>) -> Result<Solution<DrInfo>, DrError> {
        let Problem { model, loads, start, contact, data, observer, mut watch } = problem;
        let zero;
        let start = match start {
            Some(w) => w.state,
            None => {
                zero = vec![Vector3::zeros(); model.node_count()];
                &zero
            }
        };
        let mut both = |p: &Progress, u: &[Vector3<f64>]| {
            observer(p);
            if let Some(w) = watch.as_mut() {
                w(p, u);
            }
        };
        self.run(model, start, loads, contact, data, &mut both)
    }

    /// The iteration behind [`solve`](Self::solve).
    fn run(
        &self,
        model: &Model,
        start: &[Vector3<f64>],
        loads: &Loads,
        contact: &mut dyn Contact,
        data: &mut dyn DataTerm,
        observer: &mut dyn FnMut(&Progress, &[Vector3<f64>]),
    ) -> Result<Solution<DrInfo>, DrError> {
        let p = self.params;
        p.validate()?;
        let n = model.node_count();
        if loads.node_count() != n || start.len() != n {
            let got = if start.len() != n { start.len() } else { loads.node_count() };
            return Err(DrError::LoadMismatch { expected: n, got });
        }
        let start_time = Instant::now();
        let mut setup = Setup::new(model, loads, p.step_fraction, start);
        let scale = load_scale(model, loads);
        let tol = p.tolerance_unit.length(p.tolerance, scale);
        let ramp_steps = p.ramp_steps.max(1);
        let omega = Self::omega_guess(model, &setup.masses);
        let mut rayleigh = RayleighEstimator::new(n, omega, p.rho, ramp_steps, p.snapshot_interval);
        let mut guard = GrowthGuard::new(p.step_fraction, p.divergence_factor * scale);
        let mut s = State::new(model, start);
        let fitting = data.is_active();
        // Dead forces ramp in with the prescribed values from rest; a start state was in
        // balance with them (Newton–Krylov's last converged state, a session's last answer).
        let from_rest = start.iter().all(|v| *v == Vector3::zeros());
        let (mut maxd, mut below, mut err) = (0.0f64, 0usize, f64::INFINITY);
        for step in 1..=p.max_steps {
            if step > 1 && (step - 1) % REFRESH_INTERVAL == 0 {
                setup.refresh(model, &mut s, p.step_fraction);
            }
            if fitting && (step - 1) % p.snapshot_interval == 0 {
                setup.linearise(model, &mut s, p.step_fraction, data);
            }
            // Forces at the state after `step − 1` steps, and a Rayleigh snapshot if due.
            if let Err(inv) = model.internal_forces_into(&s.u, &mut s.ws, &mut s.f) {
                return Err(guard.inverted(step, inv));
            }
            if fitting {
                let pull = ramp(step as f64 / ramp_steps as f64);
                s.springs.add_forces_into(model.reference(), &s.u, pull, &mut s.f);
            }
            let weight = if from_rest { ramp(step as f64 / ramp_steps as f64) } else { 1.0 };
            loads.subtract_forces_into(weight, &mut s.f);
            rayleigh.observe(step - 1, &s.u, &s.f, &setup.masses, &setup.free, maxd);
            let (rho, load) = (rayleigh.rho(), ramp(step as f64 / ramp_steps as f64));
            setup.step(&mut s, rho, load);
            let contact_report = s.contact(model, loads, contact);
            let change = StepChange::of(&setup.free, &s.u_next, &s.u, &s.u_prev);
            guard.check(step, &change)?;
            maxd = change.maxd;
            s.advance();
            err = rayleigh.error_estimate(step, maxd);
            observer(
                &Progress {
                    step,
                    err,
                    rho,
                    load_factor: load,
                    max_displacement: change.maxu,
                    contact: contact_report,
                    linear_iterations: 0,
                    force_evaluations: step,
                },
                &s.u,
            );
            below = if err < tol { below + 1 } else { 0 };
            if below >= p.consecutive {
                let info = DrInfo {
                    steps: step,
                    err,
                    tolerance: tol,
                    rho,
                    omega_min: rayleigh.omega(),
                    contact: contact_report,
                    elapsed: start_time.elapsed(),
                };
                return Ok(Solution { displacements: s.u, report: info });
            }
        }
        Err(DrError::NoConvergence { err, steps: p.max_steps, tolerance: tol })
    }
}

impl Solver for DynamicRelaxation {
    fn name(&self) -> &'static str {
        "dr"
    }

    fn solve(&self, problem: Problem<'_>) -> Result<Solution, SolveError> {
        Ok(DynamicRelaxation::solve(self, problem)?.into_common())
    }
}
