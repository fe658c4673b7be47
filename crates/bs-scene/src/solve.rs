//! Driving a solve: the scene's `[solver]` settings become a bs-dr solver, its preparation
//! (what can be computed before the loads are known) is kept in the composition, and the
//! solve runs with a progress observer.

use bs_dr::{
    DrParams, DynamicRelaxation, MultilevelParams, Newton, NewtonKrylov, NewtonKrylovParams,
    NewtonParams, PreparedNewtonKrylov, Problem, Progress, Solution, SolveError, Solver,
    ToleranceUnit, WarmStart,
};

use crate::compose::Composed;
use crate::prepare::Prepared;
use crate::scene::SolverKind;

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
    /// Newton–Krylov keeps `K₀` to rebuild the preconditioner's coarse matrix for the contact
    /// set (`bs_dr::MultilevelParams::contact_coarse`). On by default: the MNI152 demo's cold
    /// solve takes 13 Newton / 51 GMRES iterations with it, 14 / 78 without, for about
    /// 28 MB more memory (docs/benchmarks.md).
    pub contact_coarse: bool,
    /// Newton–Krylov's preconditioner levels at most (`bs_dr::MultilevelParams::max_levels`;
    /// its default when `None`, 2 the two-level method).
    pub max_levels: Option<usize>,
}

impl SolveSettings {
    /// The settings a scene asks for.
    pub fn of(p: &Prepared) -> Self {
        SolveSettings {
            kind: p.scene.solver.kind,
            tolerance: p.scene.solver.tolerance,
            step_fraction: DrParams::default().step_fraction,
            max_steps: p.scene.solver.max_steps,
            ramp_steps: p.scene.solver.ramp_steps,
            forcing_max: None,
            contact_coarse: true,
            max_levels: None,
        }
    }
}

/// The Newton–Krylov solver for settings `s`. The scene's tolerance is a length
/// ([`ToleranceUnit::Length`]), for every solver.
pub(crate) fn newton_krylov(s: &SolveSettings) -> NewtonKrylov {
    let defaults = NewtonKrylovParams::default();
    NewtonKrylov::new(NewtonKrylovParams {
        tolerance: s.tolerance,
        tolerance_unit: ToleranceUnit::Length,
        max_iterations: s.max_steps.unwrap_or(defaults.max_iterations),
        forcing_max: s.forcing_max.unwrap_or(defaults.forcing_max),
        forcing_active_set: s
            .forcing_max
            .map_or(defaults.forcing_active_set, |f| defaults.forcing_active_set.max(f)),
        forcing_min: s.forcing_max.map_or(defaults.forcing_min, |f| defaults.forcing_min.min(f)),
        preconditioner: MultilevelParams {
            contact_coarse: s.contact_coarse,
            max_levels: s.max_levels.unwrap_or(defaults.preconditioner.max_levels),
            ..defaults.preconditioner
        },
        ..defaults
    })
}

/// The Dynamic Relaxation solver for settings `s`.
fn dynamic_relaxation(s: &SolveSettings) -> DynamicRelaxation {
    let defaults = DrParams::default();
    DynamicRelaxation::new(DrParams {
        tolerance: s.tolerance,
        tolerance_unit: ToleranceUnit::Length,
        step_fraction: s.step_fraction,
        max_steps: s.max_steps.unwrap_or(defaults.max_steps),
        ramp_steps: s.ramp_steps,
        ..defaults
    })
}

/// The dense reference Newton solver for settings `s`.
fn newton(s: &SolveSettings) -> Newton {
    Newton::new(NewtonParams {
        tolerance: s.tolerance,
        tolerance_unit: ToleranceUnit::Length,
        ..NewtonParams::default()
    })
}

/// Computes what the chosen solver can compute before the loads are known (the
/// Newton–Krylov preconditioner) and keeps it in `c`; nothing for the other solvers. A
/// preparation already in `c` that fits its loads is reused.
pub fn prepare_solver(c: &mut Composed, s: &SolveSettings) -> Result<(), SolveError> {
    if s.kind == SolverKind::NewtonKrylov
        && c.preparation.as_ref().is_none_or(|p| !p.fits(&c.loads))
    {
        c.preparation =
            Some(newton_krylov(s).prepare(&c.model, &c.loads).map_err(SolveError::from)?);
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
    solve_composed_from(c, s, None, observer)
}

/// [`solve_composed`] from a warm start (a converged state of other prescribed values: a
/// warm-started update; for Newton–Krylov possibly with the state before it, see
/// [`WarmStart`]), or from the reference state with `None`. Newton–Krylov and Dynamic
/// Relaxation move the prescribed components from their values in the start state to the
/// loads'; the dense reference Newton solver starts only from the reference state. The
/// solver is chosen by the settings and called through bs-dr's `Solver` seam.
pub fn solve_composed_from(
    c: &mut Composed,
    s: &SolveSettings,
    warm: Option<WarmStart<'_>>,
    observer: &mut dyn FnMut(&Progress),
) -> Result<(Solution, f64), SolveError> {
    let mut max_penetration = 0.0f64;
    let mut observe = |pr: &Progress| {
        max_penetration = max_penetration.max(pr.contact.max_penetration);
        observer(pr);
    };
    prepare_solver(c, s)?;
    // The contact time of this solve only (a live session keeps its handler across updates).
    if let Some(sc) = &mut c.contact {
        sc.elapsed = std::time::Duration::ZERO;
    }
    let mut none = bs_dr::NoContact;
    let contact: &mut dyn bs_dr::Contact = match &mut c.contact {
        Some(sc) => sc,
        None => &mut none,
    };
    let mut no_data = bs_dr::NoData;
    let data: &mut dyn bs_dr::DataTerm = match &mut c.fit {
        Some(f) => &mut f.fits,
        None => &mut no_data,
    };
    let problem = Problem {
        model: &c.model,
        loads: &c.loads,
        start: warm,
        contact,
        data,
        observer: &mut observe,
        watch: None,
    };
    let nk = newton_krylov(s);
    let solver: Box<dyn Solver + '_> = match s.kind {
        SolverKind::NewtonKrylov => {
            let preparation = c.preparation.as_ref().expect("prepared above");
            Box::new(PreparedNewtonKrylov { solver: &nk, preparation })
        }
        SolverKind::Dr => Box::new(dynamic_relaxation(s)),
        SolverKind::Newton => Box::new(newton(s)),
    };
    let solution = solver.solve(problem)?;
    drop(solver);
    relinearise_at(c, &solution.displacements);
    Ok((solution, max_penetration))
}

/// The measurements linearised at the answer `u`: their springs (the data forces the
/// verification balances) and their per-point state (what the reports say) are those of
/// the answer.
pub(crate) fn relinearise_at(c: &mut Composed, u: &[bs_mesh::Vector3<f64>]) {
    let Some(fit) = &mut c.fit else { return };
    let positions: Vec<bs_mesh::Point3<f64>> =
        c.model.reference().iter().zip(u).map(|(x, d)| x + d).collect();
    bs_dr::DataTerm::linearise(&mut fit.fits, &positions, &mut fit.springs);
    fit.fits.classify(&positions);
}
