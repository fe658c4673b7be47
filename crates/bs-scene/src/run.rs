//! A run: a prepared scene composed, its solver prepared (everything that depends only on
//! mesh, materials and skull: what a hospital can compute before surgery), solved, and the
//! result verified. Front ends (the `brainshift` binary, bindings, studies) drive this and
//! decide how to show progress; nothing here prints.

use std::time::Instant;

use bs_dr::{Progress, Solution};

use crate::SceneError;
use crate::compose::{Composed, compose};
use crate::measure::dispatch::solve_measured;
use crate::measure::{MeasurementReport, PointRow};
use crate::prepare::Prepared;
use crate::solve::{SolveSettings, prepare_solver};
use crate::verify::{Verification, verify};

/// A scene ready to solve.
#[derive(Debug)]
pub struct Run {
    /// The scene with its files read and names resolved.
    pub prepared: Prepared,
    /// Model, loads, contact and the solver's preparation.
    pub composed: Composed,
    /// How the solve is driven.
    pub settings: SolveSettings,
    /// Wall time of composition, the initial check and the solver's preparation (seconds).
    pub prepare_seconds: f64,
}

/// A verified result.
#[derive(Debug)]
pub struct Solved {
    /// Displacements and the solver's report.
    pub solution: Solution,
    /// Largest penetration any slave had before it was corrected (over all steps).
    pub max_penetration_before: f64,
    /// The independent checks the result passed.
    pub verification: Verification,
    /// Wall time from known displacements to the verified result (seconds).
    pub solve_seconds: f64,
    /// Per `[[measurement]]`: what the fit did (empty without measurements).
    pub measurements: Vec<MeasurementReport>,
    /// Per measured point: its residual, weight and status (residuals.csv).
    pub residuals: Vec<PointRow>,
    /// The gravity solved with and what was estimated of it (`None` without `[gravity]`).
    pub gravity: Option<crate::estimate::GravityReport>,
    /// σ of the fitted answer, when asked for (bs-scene's `uncertainty::sample`).
    pub uncertainty: Option<crate::uncertainty::sigma::Uncertainty>,
    /// Why the measurements could not be used, when they could not: the answer is then the
    /// prior's (the scene without them, or at gravity's estimate), verified without them.
    pub data_unused: Option<String>,
}

impl Solved {
    /// The verified result of `solution` on `run`'s scene, with its measurements' outcome.
    pub(crate) fn new(
        prepared: &Prepared,
        composed: &Composed,
        solution: Solution,
        max_penetration_before: f64,
        verification: Verification,
        solve_seconds: f64,
    ) -> Solved {
        let (measurements, residuals) = match &composed.fit {
            Some(f) => crate::measure::outcome::outcome(prepared, f, &solution.displacements),
            None => (Vec::new(), Vec::new()),
        };
        Solved {
            solution,
            max_penetration_before,
            verification,
            solve_seconds,
            measurements,
            residuals,
            gravity: prepared.scene.gravity.as_ref().map(|g| crate::estimate::GravityReport {
                data_used: composed.fit.is_some(),
                ..crate::estimate::GravityReport::of(g)
            }),
            uncertainty: None,
            data_unused: None,
        }
    }
}

impl Run {
    /// Composes `prepared`, refuses it if the memory estimate exceeds what the machine has
    /// or a brain node starts outside the skull, and prepares the solver.
    pub fn prepare(prepared: Prepared) -> Result<Run, SceneError> {
        crate::memory::require_fits(&prepared, crate::memory::available())?;
        let started = Instant::now();
        let mut composed = compose(&prepared)?;
        composed.check_initial_gap(&prepared)?;
        let settings = SolveSettings::of(&prepared);
        prepare_solver(&mut composed, &settings)?;
        Ok(Run { prepared, composed, settings, prepare_seconds: started.elapsed().as_secs_f64() })
    }

    /// Solves and verifies; `observer` sees every step (DR) or iteration (Newton solvers).
    pub fn solve(&mut self, observer: &mut dyn FnMut(&Progress)) -> Result<Solved, SceneError> {
        let started = Instant::now();
        let (p, c) = (&mut self.prepared, &mut self.composed);
        let answer = solve_measured(p, c, &self.settings, None, observer)?;
        let (solution, max_penetration_before) = (answer.solution, answer.penetration);
        let (estimated, unused) = (answer.gravity, answer.unused);
        let kept = crate::estimate::unused_data(&mut self.composed, unused.is_some());
        let verification = verify(
            &self.prepared,
            &self.composed,
            &solution.displacements,
            self.settings.tolerance,
        );
        let seconds = started.elapsed().as_secs_f64();
        let (p, c) = (&self.prepared, &self.composed);
        let solved =
            verification.map(|v| Solved::new(p, c, solution, max_penetration_before, v, seconds));
        crate::estimate::restore(&mut self.composed, kept);
        let mut solved = solved?;
        if estimated.is_some() {
            solved.gravity = estimated;
        }
        solved.data_unused = unused;
        Ok(solved)
    }
}
