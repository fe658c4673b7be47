//! One scene solved with variations: element technology, solver, tolerance, contact handler,
//! time-step fraction, hourglass control, Poisson's ratio, load. This is what
//! `cargo xtask validate`, `chart` and `stability` measure, and what `run` itself uses to
//! solve, so a study measures exactly the code path of `brainshift run`.

use std::time::Instant;

use bs_contact::PaperParams;
use bs_dr::{
    DrParams, DynamicRelaxation, Newton, NewtonKrylov, NewtonKrylovParams, NewtonParams, Progress,
    Solution, SolveError, Solver,
};
use nalgebra::Vector3;

use crate::check::Prepared;
use crate::compose::{ComposeOptions, Composed, compose_with};
use crate::scene::{Algorithm, ElementChoice, SolverKind};

/// How a solve is driven: the scene's `[solver]` table plus the step fraction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveSettings {
    /// DR or Newton.
    pub kind: SolverKind,
    /// Error-estimate tolerance in mesh length units.
    pub tolerance: f64,
    /// DR time step as a fraction of the critical step (bs-dr's default 0.8).
    pub step_fraction: f64,
    /// DR step budget (bs-dr's default when `None`).
    pub max_steps: Option<usize>,
    /// DR steps of the load ramp.
    pub ramp_steps: usize,
    /// Newton–Krylov's largest linear-solve relative residual (its default when `None`).
    pub forcing_max: Option<f64>,
}

impl SolveSettings {
    /// The settings a scene asks for.
    pub fn of(p: &Prepared) -> Self {
        SolveSettings {
            kind: p.scene.solver.kind,
            tolerance: p.scene.solver.tolerance,
            step_fraction: DrParams::default().step_fraction,
            max_steps: None,
            ramp_steps: p.scene.solver.ramp_steps,
            forcing_max: None,
        }
    }
}

/// The Newton–Krylov solver for settings `s` on composition `c`.
fn newton_krylov(c: &Composed, s: &SolveSettings) -> NewtonKrylov {
    newton_krylov_params(s, c.load_scale)
}

fn newton_krylov_params(s: &SolveSettings, load_scale: f64) -> NewtonKrylov {
    let defaults = NewtonKrylovParams::default();
    NewtonKrylov::new(NewtonKrylovParams {
        tolerance: s.tolerance / load_scale,
        max_iterations: s.max_steps.unwrap_or(defaults.max_iterations),
        forcing_max: s.forcing_max.unwrap_or(defaults.forcing_max),
        forcing_active_set: s
            .forcing_max
            .map_or(defaults.forcing_active_set, |f| defaults.forcing_active_set.max(f)),
        forcing_min: s.forcing_max.map_or(defaults.forcing_min, |f| defaults.forcing_min.min(f)),
        ..defaults
    })
}

/// Computes what the chosen solver can compute before the loads are known (the
/// Newton–Krylov preconditioner) and keeps it in `c`; nothing for the other solvers. A
/// preparation already in `c` that fits its loads is reused.
pub fn prepare_solver(c: &mut Composed, s: &SolveSettings) -> Result<(), SolveError> {
    if s.kind == SolverKind::NewtonKrylov
        && c.preparation.as_ref().is_none_or(|p| !p.fits(&c.loads))
    {
        c.preparation = Some(newton_krylov(c, s).prepare(&c.model, &c.loads)?);
    }
    Ok(())
}

/// Solves a composed scene, returning the solution and the largest penetration any slave
/// had before it was corrected (over all steps).
pub fn solve_composed(
    c: &mut Composed,
    s: &SolveSettings,
    observer: &mut dyn FnMut(&Progress),
) -> Result<(Solution, f64), SolveError> {
    let relative = s.tolerance / c.load_scale;
    let mut max_penetration = 0.0f64;
    let mut observe = |pr: &Progress| {
        max_penetration = max_penetration.max(pr.contact.max_penetration);
        observer(pr);
    };
    prepare_solver(c, s)?;
    let mut none = bs_dr::NoContact;
    let contact: &mut dyn bs_dr::Contact = match &mut c.contact {
        Some(sc) => sc,
        None => &mut none,
    };
    let solution = match s.kind {
        SolverKind::NewtonKrylov => {
            let prep = c.preparation.as_ref().expect("prepared above");
            newton_krylov_params(s, c.load_scale).solve_prepared(
                &c.model,
                &c.loads,
                prep,
                contact,
                &mut observe,
            )
        }
        SolverKind::Dr => {
            let defaults = DrParams::default();
            DynamicRelaxation::new(DrParams {
                tolerance: relative,
                step_fraction: s.step_fraction,
                max_steps: s.max_steps.unwrap_or(defaults.max_steps),
                ramp_steps: s.ramp_steps,
                ..defaults
            })
            .solve(&c.model, &c.loads, contact, &mut observe)
        }
        SolverKind::Newton => {
            Newton::new(NewtonParams { tolerance: relative, ..NewtonParams::default() }).solve(
                &c.model,
                &c.loads,
                contact,
                &mut observe,
            )
        }
    }?;
    Ok((solution, max_penetration))
}

/// Contact state of a result, measured exactly (parry's BVH and the exact point–triangle
/// projection, independent of the handler the solver used; once per solve).
#[derive(Debug, Clone, PartialEq)]
pub struct ContactState {
    /// Per node: 1 if the node is a slave within the tolerance of the skull, else 0.
    pub in_contact: Vec<f64>,
    /// Largest distance of any slave outside the skull (0 if none).
    pub max_penetration: f64,
    /// Slaves outside by more than the tolerance, and the worst one (node index, distance).
    pub outside: usize,
    /// The slave farthest outside beyond the tolerance.
    pub worst: Option<(usize, f64)>,
}

/// The contact state of displacements `u` with tolerance `tol` (no skull: nothing in
/// contact, nothing outside).
pub fn contact_state(p: &Prepared, c: &Composed, u: &[Vector3<f64>], tol: f64) -> ContactState {
    let mut st = ContactState {
        in_contact: vec![0.0; p.mesh.nodes.len()],
        max_penetration: 0.0,
        outside: 0,
        worst: None,
    };
    if let Some(exact) = &c.exact {
        let points = c.slaves.iter().map(|&i| p.mesh.nodes[i] + u[i]);
        for (row, &i) in crate::compose::exact_gaps(exact, points).iter().zip(&c.slaves) {
            if row.signed_distance <= tol {
                st.in_contact[i] = 1.0;
            }
            if row.outside {
                let d = -row.signed_distance;
                st.max_penetration = st.max_penetration.max(d);
                if d > tol {
                    st.outside += 1;
                    if st.worst.is_none_or(|(_, w)| d > w) {
                        st.worst = Some((i, d));
                    }
                }
            }
        }
    }
    st
}

/// The last guard of a run: per node 1 if in contact (see [`ContactState`]) and the largest
/// penetration, or an error naming the worst node when a slave ended outside the skull by
/// more than `tol` (a contact handler that missed penetrations, e.g. without the §3.2
/// additional lists at a sharp skull corner). Such a result is never written.
pub fn final_contact(
    p: &Prepared,
    c: &Composed,
    u: &[Vector3<f64>],
    tol: f64,
) -> Result<(Vec<f64>, f64), String> {
    let st = contact_state(p, c, u, tol);
    if let Some((i, d)) = st.worst {
        return Err(format!(
            "contact check failed: {} brain surface node{} ended outside the skull by more \
             than the tolerance {tol:e}; worst: node {} by {d:.3e}. The contact handler missed \
             penetrations; run the scene with algorithm = \"brute-force\" to confirm",
            st.outside,
            if st.outside == 1 { "" } else { "s" },
            p.mesh.node_ids[i]
        ));
    }
    Ok((st.in_contact, st.max_penetration))
}

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
}

/// Why a variant produced no result.
#[derive(Debug, Clone, PartialEq)]
pub enum Failure {
    /// The variant does not apply to the scene, or composing it failed.
    Setup(String),
    /// The solver stopped with a typed error.
    Solve(SolveError),
    /// The solver converged but the result failed the post-solve contact check.
    Check(String),
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::Setup(e) => write!(f, "setup: {e}"),
            Failure::Solve(e) => write!(f, "the solver stopped: {e}"),
            Failure::Check(e) => f.write_str(e),
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
    /// Smallest element volume ratio J of the result (≤ 0: an inverted element).
    pub min_volume_ratio: f64,
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
        let mut c = compose_with(&q, &opts).map_err(|e| Failure::Setup(e.0))?;
        let setup_seconds = started.elapsed().as_secs_f64();
        let mut settings = SolveSettings::of(&q);
        if let Some(f) = self.step_fraction {
            settings.step_fraction = f;
        }
        settings.max_steps = self.max_steps;
        settings.forcing_max = self.forcing_max;
        prepare_solver(&mut c, &settings).map_err(Failure::Solve)?;
        let prepare_seconds = started.elapsed().as_secs_f64();
        let solving = Instant::now();
        let (solution, max_penetration_before) =
            solve_composed(&mut c, &settings, &mut |_| {}).map_err(Failure::Solve)?;
        let u = solution.displacements;
        let (in_contact, max_penetration_after) =
            final_contact(&q, &c, &u, settings.tolerance).map_err(Failure::Check)?;
        let solve_seconds = solving.elapsed().as_secs_f64();
        let min_volume_ratio = c
            .model
            .element_measures(&u)
            .map(|m| m.volume_ratio.iter().copied().fold(f64::INFINITY, f64::min))
            .unwrap_or(f64::NAN);
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
            max_penetration_after,
            nodes_in_contact: in_contact.iter().filter(|&&x| x > 0.0).count(),
            min_volume_ratio,
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
