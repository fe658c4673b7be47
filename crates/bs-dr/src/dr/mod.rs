//! Adaptive Dynamic Relaxation (the explicit steady-state solver).
//!
//! The iteration (Joldes, Wittek & Miller's adaptive DR, a second-order Richardson
//! iteration with mass-proportional damping), with pseudo time step `h = 1`:
//!
//! `u⁺ = u + ρ² (u − u⁻) + ((1+ρ) h / 2)² M⁻¹ (f_ext − f_int(u))`, `f_ext = 0` (zero traction).
//!
//! * Masses are fictitious ([`Model::dr_masses_into`]): element `e` gets the mass that makes
//!   its own critical step `h / step_fraction`, so every node has the same stable step.
//! * The convergence rate `ρ = (κ − 1)/(κ + 1)`, `κ = 2/(ω_min h)`, comes from a
//!   Rayleigh-quotient estimate of the lowest eigenvalue of `M⁻¹K` taken from snapshots every
//!   `snapshot_interval` steps after the ramp: `ω²_min ≈ |Δuᵀ Δf| / (Δuᵀ M Δu)` over free
//!   DOFs. A new ρ is accepted once two successive estimates agree within 10%. Before that a
//!   geometric guess is used (quarter-wave of the fictitious shear wave over the bounding-box
//!   diagonal).
//! * Termination: `err = max|Δu| ρₑ/(1 − ρₑ) < tolerance × load scale` for `consecutive`
//!   steps in a row, never a fixed step count. `ρₑ` is the more pessimistic of the rate from
//!   `0.9 ω_min` and the decay rate of `max|Δu|` observed over the last snapshot window.
//! * Prescribed components follow the 3-4-5 ramp over `ramp_steps` steps, then stay.
//! * Guard: non-finite values, an inverted element, alternating growth of `Δu` (time step
//!   above critical) and displacements beyond `divergence_factor × load scale` stop the run
//!   with a typed [`SolveError`].

use std::time::Instant;

use bs_mesh::{Point3, Vector3};

use crate::contact::Contact;
use crate::loads::{Loads, ramp};
use crate::model::Model;
use crate::solver::{Progress, Report, Solution, SolveError, Solver, check_param, load_scale};

/// Parameters of [`DynamicRelaxation`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrParams {
    /// Convergence tolerance on the error estimate, relative to the load scale (the largest
    /// prescribed displacement component, or the bounding-box diagonal if none). Default 1e-6.
    pub tolerance: f64,
    /// Consecutive steps the error estimate must stay below the tolerance. Default 10.
    pub consecutive: usize,
    /// Step budget. Default 200 000.
    pub max_steps: usize,
    /// Steps of the 3-4-5 ramp of the prescribed displacements. Default 200.
    pub ramp_steps: usize,
    /// Time step as a fraction of the element critical step (< 1 is stable). Default 0.8.
    pub step_fraction: f64,
    /// Steps between Rayleigh-quotient snapshots. Default 100.
    pub snapshot_interval: usize,
    /// A fixed convergence rate ρ ∈ [0, 1) instead of the adaptive estimate. Default `None`.
    pub rho: Option<f64>,
    /// Divergence bound on `max|u|` as a multiple of the load scale. Default 100.
    pub divergence_factor: f64,
}

impl Default for DrParams {
    fn default() -> Self {
        DrParams {
            tolerance: 1e-6,
            consecutive: 10,
            max_steps: 200_000,
            ramp_steps: 200,
            step_fraction: 0.8,
            snapshot_interval: 100,
            rho: None,
            divergence_factor: 100.0,
        }
    }
}

/// The adaptive Dynamic Relaxation solver.
#[derive(Debug, Clone, Copy, Default)]
pub struct DynamicRelaxation {
    /// Parameters.
    pub params: DrParams,
}

/// `ρ = (κ − 1)/(κ + 1)` with `κ = 2/(ω h)`, `h = 1`.
fn rho_of(omega: f64) -> f64 {
    let w = omega.clamp(1e-12, 2.0);
    (2.0 - w) / (2.0 + w)
}

/// Alternating-growth detector: steps in a row with `Δu_k · Δu_{k−1} < −½ |Δu_k||Δu_{k−1}|`
/// and `|Δu_k| > 1.25 |Δu_{k−1}|`.
const GROWTH_RATIO: f64 = 1.25;
const GROWTH_STEPS: usize = 4;

impl DynamicRelaxation {
    /// A solver with the given parameters.
    pub fn new(params: DrParams) -> Self {
        DynamicRelaxation { params }
    }

    fn validate(&self) -> Result<(), SolveError> {
        let p = &self.params;
        check_param("tolerance", p.tolerance, p.tolerance > 0.0, "must be > 0")?;
        check_param("consecutive", p.consecutive as f64, p.consecutive >= 1, "must be >= 1")?;
        check_param("max_steps", p.max_steps as f64, p.max_steps >= 1, "must be >= 1")?;
        check_param(
            "step_fraction",
            p.step_fraction,
            p.step_fraction > 0.0,
            "must be > 0 (< 1 is stable)",
        )?;
        check_param(
            "snapshot_interval",
            p.snapshot_interval as f64,
            p.snapshot_interval >= 2,
            "must be >= 2",
        )?;
        if let Some(r) = p.rho {
            check_param("rho", r, (0.0..1.0).contains(&r), "must lie in [0, 1)")?;
        }
        check_param(
            "divergence_factor",
            p.divergence_factor,
            p.divergence_factor > 1.0,
            "must be > 1",
        )?;
        Ok(())
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
}

impl Solver for DynamicRelaxation {
    fn name(&self) -> &'static str {
        "dynamic-relaxation"
    }

    fn solve(
        &self,
        model: &Model,
        loads: &Loads,
        contact: &mut dyn Contact,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Solution, SolveError> {
        self.validate()?;
        let p = self.params;
        let n = model.node_count();
        if loads.node_count() != n {
            return Err(SolveError::LoadMismatch { expected: n, got: loads.node_count() });
        }
        let start = Instant::now();
        let mut masses = vec![0.0; n];
        model.dr_masses_into(p.step_fraction, &mut masses);
        let inv_m: Vec<f64> = masses.iter().map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 }).collect();
        let (free, fixed) = loads.split_dofs();
        let fixed_value: Vec<f64> = fixed.iter().map(|&d| loads.value(d / 3, d % 3)).collect();
        let scale = load_scale(model, loads);
        let tol = p.tolerance * scale;
        let limit = p.divergence_factor * scale;
        let reference = model.reference();

        let mut u = vec![Vector3::<f64>::zeros(); n];
        let mut u_prev = u.clone();
        let mut u_next = u.clone();
        let mut f = u.clone();
        let mut snap_u = u.clone();
        let mut snap_f = u.clone();
        let mut positions: Vec<Point3<f64>> = reference.to_vec();
        let mut ws = model.workspace();

        let mut omega = Self::omega_guess(model, &masses);
        let mut rho = p.rho.unwrap_or_else(|| rho_of(omega));
        let mut last_estimate: Option<f64> = None;
        let mut have_snapshot = false;
        let mut snap_maxd = 0.0f64;
        let mut rate_obs: Option<f64> = None;
        let mut maxd = 0.0f64;
        let mut below = 0usize;
        let mut growth_count = 0usize;
        let mut growth_log = 0.0;
        let mut err = f64::INFINITY;
        let ramp_steps = p.ramp_steps.max(1);
        let m = p.snapshot_interval;

        for step in 1..=p.max_steps {
            // Forces at the state after `step − 1` steps.
            if let Err(inv) = model.internal_forces_into(&u, &mut ws, &mut f) {
                if growth_count >= 2 {
                    return Err(SolveError::Unstable {
                        step,
                        growth: (growth_log / growth_count as f64).exp(),
                        steps: growth_count,
                        step_fraction: p.step_fraction,
                    });
                }
                return Err(SolveError::ElementInverted {
                    step,
                    element: inv.element,
                    element_id: inv.element_id,
                    jacobian: inv.jacobian,
                });
            }
            // Rayleigh-quotient snapshots after the ramp.
            let k = step - 1;
            if k >= ramp_steps && (k - ramp_steps).is_multiple_of(m) {
                if have_snapshot {
                    let (mut num, mut den) = (0.0, 0.0);
                    for &d in &free {
                        let (a, c) = (d / 3, d % 3);
                        let du = u[a][c] - snap_u[a][c];
                        num += du * (f[a][c] - snap_f[a][c]);
                        den += masses[a] * du * du;
                    }
                    if den > 0.0 && num.is_finite() {
                        let est = (num.abs() / den).sqrt();
                        if p.rho.is_none()
                            && let Some(prev) = last_estimate
                            && (est - prev).abs() <= 0.1 * est
                        {
                            omega = est;
                            rho = rho_of(omega);
                        }
                        last_estimate = Some(est);
                    }
                    rate_obs = Some(if snap_maxd > 0.0 {
                        (maxd / snap_maxd).powf(1.0 / m as f64)
                    } else {
                        0.0
                    });
                }
                snap_u.copy_from_slice(&u);
                snap_f.copy_from_slice(&f);
                snap_maxd = maxd;
                have_snapshot = true;
            }

            // Update.
            let load = ramp(step as f64 / ramp_steps as f64);
            let beta = 0.25 * (1.0 + rho) * (1.0 + rho);
            let r2 = rho * rho;
            for &d in &free {
                let (a, c) = (d / 3, d % 3);
                u_next[a][c] = u[a][c] + r2 * (u[a][c] - u_prev[a][c]) - beta * f[a][c] * inv_m[a];
            }
            for (i, &d) in fixed.iter().enumerate() {
                u_next[d / 3][d % 3] = fixed_value[i] * load;
            }
            // Contact on the current positions.
            for (x, (x0, un)) in positions.iter_mut().zip(reference.iter().zip(&u_next)) {
                *x = x0 + un;
            }
            let last_contact = contact.enforce(&mut positions);
            for a in 0..n {
                let x = positions[a];
                if x != reference[a] + u_next[a] {
                    let moved = x - reference[a];
                    for c in 0..3 {
                        if !loads.is_constrained(a, c) {
                            u_next[a][c] = moved[c];
                        }
                    }
                }
            }
            // Statistics over free DOFs.
            maxd = 0.0f64;
            let (mut dot, mut nk, mut nk1) = (0.0, 0.0, 0.0);
            for &d in &free {
                let (a, c) = (d / 3, d % 3);
                let dk = u_next[a][c] - u[a][c];
                let dk1 = u[a][c] - u_prev[a][c];
                maxd = maxd.max(dk.abs());
                dot += dk * dk1;
                nk += dk * dk;
                nk1 += dk1 * dk1;
            }
            let maxu = u_next.iter().fold(0.0f64, |acc, v| acc.max(v.norm()));
            if !(maxd.is_finite() && maxu.is_finite() && nk.is_finite()) {
                return Err(SolveError::NotFinite { step });
            }
            if nk1 > 0.0 && dot < -0.5 * (nk * nk1).sqrt() && nk > GROWTH_RATIO * GROWTH_RATIO * nk1
            {
                growth_count += 1;
                growth_log += 0.5 * (nk / nk1).ln();
                if growth_count >= GROWTH_STEPS {
                    return Err(SolveError::Unstable {
                        step,
                        growth: (growth_log / growth_count as f64).exp(),
                        steps: growth_count,
                        step_fraction: p.step_fraction,
                    });
                }
            } else {
                growth_count = 0;
                growth_log = 0.0;
            }
            if maxu > limit {
                return Err(SolveError::Diverged { step, max_displacement: maxu, limit });
            }
            std::mem::swap(&mut u_prev, &mut u);
            std::mem::swap(&mut u, &mut u_next);

            err = match rate_obs {
                Some(r) if step >= ramp_steps => {
                    let rho_e = rho_of(0.9 * omega).max(rho).max(r);
                    if rho_e < 1.0 { maxd * rho_e / (1.0 - rho_e) } else { f64::INFINITY }
                }
                _ => f64::INFINITY,
            };
            observer(&Progress {
                step,
                err,
                rho,
                load_factor: load,
                max_displacement: maxu,
                contact: last_contact,
                linear_iterations: 0,
                force_evaluations: step,
            });
            if err < tol {
                below += 1;
                if below >= p.consecutive {
                    return Ok(Solution {
                        displacements: u,
                        report: Report {
                            solver: self.name(),
                            steps: step,
                            err,
                            tolerance: tol,
                            rho,
                            omega_min: omega,
                            contact: last_contact,
                            force_evaluations: step,
                            linear_iterations: 0,
                            breakdown: Default::default(),
                            elapsed: start.elapsed(),
                        },
                    });
                }
            } else {
                below = 0;
            }
        }
        Err(SolveError::NoConvergence { err, steps: p.max_steps, tolerance: tol })
    }
}
