//! One scene solved with variations: element technology, solver, tolerance, contact handler,
//! time-step fraction, hourglass control, Poisson's ratio, load. This is what
//! `cargo xtask validate`, `chart` and `stability` measure, and what `run` itself uses to
//! solve, so a study measures exactly the code path of `brainshift run`.

use std::time::Instant;

use bs_contact::PaperParams;
use bs_dr::{Progress, SolveError};
use nalgebra::Vector3;

use bs_scene::compose::{ComposeOptions, compose_with};
use bs_scene::prepare::Prepared;
use bs_scene::scene::{Algorithm, ElementChoice, SolverKind};
use bs_scene::solve::{SolveSettings, prepare_solver, solve_composed};
use bs_scene::verify::verify;

/// The contact of a variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactChoice {
    /// No skull.
    Off,
    /// The scene's skull with this handler.
    Handler(Algorithm),
}

/// What to change in a scene; `None` keeps the scene's own setting.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Variant {
    /// Element technology (H8 only for hexahedral meshes, T4/T4ANP only for tetrahedral).
    pub element: Option<ElementChoice>,
    /// Solver kind.
    pub solver: Option<SolverKind>,
    /// Error-estimate tolerance, mesh length units.
    pub tolerance: Option<f64>,
    /// Contact handler, or no contact.
    pub contact: Option<ContactChoice>,
    /// DR time step as a fraction of the critical step.
    pub step_fraction: Option<f64>,
    /// H8 hourglass coefficient (0 = no control).
    pub hourglass: Option<f64>,
    /// Poisson's ratio of every region given by (E, ν) (E kept).
    pub poisson_ratio: Option<f64>,
    /// Factor on every prescribed (non-zero) displacement.
    pub load_factor: Option<f64>,
    /// The paper's §3.2 additional lists on or off.
    pub additional_lists: Option<bool>,
    /// DR step budget.
    pub max_steps: Option<usize>,
    /// DR steps of the load ramp.
    pub ramp_steps: Option<usize>,
    /// Newton–Krylov's largest linear-solve relative residual.
    pub forcing_max: Option<f64>,
    /// Newton–Krylov's preconditioner levels at most (2: the two-level method).
    pub max_levels: Option<usize>,
}

/// Why a variant produced no result.
#[derive(Debug, Clone, PartialEq)]
pub enum Failure {
    /// The variant does not apply to the scene, or composing it failed.
    Setup(String),
    /// The solver stopped with a typed error.
    Solve(SolveError),
    /// The solver converged but the result failed verification (contact, J, equilibrium).
    Check(bs_scene::verify::VerifyError),
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::Setup(e) => write!(f, "setup: {e}"),
            Failure::Solve(e) => write!(f, "the solver stopped: {e}"),
            Failure::Check(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for Failure {}

/// A solved variant.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Nodal displacements, mesh node order.
    pub displacements: Vec<Vector3<f64>>,
    /// DR steps or Newton iterations.
    pub steps: usize,
    /// Wall time of model and contact setup (seconds).
    pub setup_seconds: f64,
    /// Wall time of everything that depends only on mesh, materials and skull: the setup
    /// and the solver's preparation (the Newton–Krylov preconditioner) (seconds).
    pub prepare_seconds: f64,
    /// Wall time of the solver alone (seconds).
    pub solver_seconds: f64,
    /// Wall time from known displacements to a converged, checked result: the solver and
    /// the final contact check (seconds).
    pub solve_seconds: f64,
    /// Evaluations of the internal forces.
    pub force_evaluations: usize,
    /// Inner linear-solver iterations (Newton–Krylov's GMRES).
    pub linear_iterations: usize,
    /// Part of the solve spent in contact enforcement (seconds).
    pub contact_seconds: f64,
    /// Final error estimate, mesh length units.
    pub error_estimate: f64,
    /// Largest penetration before correction over all steps.
    pub max_penetration_before: f64,
    /// Largest distance of a slave outside the skull in the result.
    pub max_penetration_after: f64,
    /// Slaves on the skull (within the tolerance) at the end.
    pub nodes_in_contact: usize,
    /// Smallest element volume ratio J of the result (> 0: verified).
    pub min_volume_ratio: f64,
    /// Largest out-of-balance force at a free node relative to the largest reaction
    /// (verified against [`bs_scene::verify::equilibrium_bound`]).
    pub equilibrium_residual: f64,
}

impl Variant {
    /// The scene with this variant's changes applied.
    pub fn apply(&self, p: &Prepared) -> Result<Prepared, Failure> {
        let mut q = p.clone();
        if let Some(e) = self.element {
            let (tets, hexes) = q.mesh.count_by_kind();
            let fits = match e {
                ElementChoice::H8 => tets == 0,
                ElementChoice::T4 | ElementChoice::T4anp => hexes == 0,
            };
            if !fits {
                return Err(Failure::Setup(format!(
                    "element {e:?} does not fit a mesh of {tets} tetrahedra and {hexes} hexahedra"
                )));
            }
            q.element = e;
            q.scene.mesh.element = Some(e);
        }
        if let Some(k) = self.solver {
            q.scene.solver.kind = k;
        }
        if let Some(t) = self.tolerance {
            q.scene.solver.tolerance = t;
        }
        if let Some(r) = self.ramp_steps {
            q.scene.solver.ramp_steps = r;
        }
        match self.contact {
            Some(ContactChoice::Off) => {
                q.scene.contact = None;
                q.skull = None;
            }
            Some(ContactChoice::Handler(a)) => match &mut q.scene.contact {
                Some(c) => c.algorithm = a,
                None => {
                    return Err(Failure::Setup(
                        "the scene has no skull to use a handler on".into(),
                    ));
                }
            },
            None => {}
        }
        if let Some(nu) = self.poisson_ratio {
            for r in &mut q.scene.regions {
                if r.material.poisson_ratio.is_none() {
                    return Err(Failure::Setup(format!(
                        "region '{}' is given by shear and bulk moduli, not (E, ν)",
                        r.elset
                    )));
                }
                r.material.poisson_ratio = Some(nu);
            }
        }
        if let Some(f) = self.load_factor {
            for comps in &mut q.prescribed {
                for v in comps.iter_mut().flatten() {
                    *v *= f;
                }
            }
        }
        Ok(q)
    }

    /// Solves the scene with this variant.
    pub fn solve(&self, p: &Prepared) -> Result<Outcome, Failure> {
        self.solve_observed(p, &mut |_| {})
    }

    /// [`Variant::solve`], calling `observer` once per DR step or Newton iteration (what a
    /// run that stops early reached: its load fraction, iterations and force evaluations).
    pub fn solve_observed(
        &self,
        p: &Prepared,
        observer: &mut dyn FnMut(&Progress),
    ) -> Result<Outcome, Failure> {
        let q = self.apply(p)?;
        let defaults = ComposeOptions::default();
        let opts = ComposeOptions {
            hourglass: self.hourglass.unwrap_or(defaults.hourglass),
            contact: PaperParams {
                additional_lists: self
                    .additional_lists
                    .unwrap_or(defaults.contact.additional_lists),
                ..defaults.contact
            },
        };
        let started = Instant::now();
        let mut c = compose_with(&q, &opts).map_err(|e| Failure::Setup(e.to_string()))?;
        let setup_seconds = started.elapsed().as_secs_f64();
        let mut settings = SolveSettings::of(&q);
        if let Some(f) = self.step_fraction {
            settings.step_fraction = f;
        }
        if self.max_steps.is_some() {
            settings.max_steps = self.max_steps;
        }
        settings.forcing_max = self.forcing_max;
        settings.max_levels = self.max_levels;
        prepare_solver(&mut c, &settings).map_err(Failure::Solve)?;
        let prepare_seconds = started.elapsed().as_secs_f64();
        let solving = Instant::now();
        let (solution, max_penetration_before) =
            solve_composed(&mut c, &settings, observer).map_err(Failure::Solve)?;
        let u = solution.displacements;
        let v = verify(&q, &c, &u, settings.tolerance).map_err(Failure::Check)?;
        let solve_seconds = solving.elapsed().as_secs_f64();
        Ok(Outcome {
            steps: solution.report.steps,
            setup_seconds,
            prepare_seconds,
            solver_seconds: solution.report.elapsed.as_secs_f64(),
            solve_seconds,
            force_evaluations: solution.report.force_evaluations,
            linear_iterations: solution.report.linear_iterations,
            contact_seconds: c.contact.as_ref().map_or(0.0, |sc| sc.elapsed.as_secs_f64()),
            error_estimate: solution.report.err,
            max_penetration_before,
            max_penetration_after: v.max_penetration_after,
            nodes_in_contact: v.in_contact.iter().filter(|&&x| x > 0.0).count(),
            min_volume_ratio: v.min_jacobian,
            equilibrium_residual: v.equilibrium_residual,
            displacements: u,
        })
    }
}

/// Mean and largest Euclidean distance between two displacement fields over `nodes` (all
/// nodes when `None`).
pub fn difference(a: &[Vector3<f64>], b: &[Vector3<f64>], nodes: Option<&[usize]>) -> (f64, f64) {
    let mut sum = 0.0;
    let mut max = 0.0f64;
    let mut n = 0usize;
    let mut add = |i: usize| {
        let d = (a[i] - b[i]).norm();
        sum += d;
        max = max.max(d);
        n += 1;
    };
    match nodes {
        Some(list) => list.iter().for_each(|&i| add(i)),
        None => (0..a.len().min(b.len())).for_each(&mut add),
    }
    (if n == 0 { 0.0 } else { sum / n as f64 }, max)
}
