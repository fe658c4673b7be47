//! One measured cell: a variant solved with an observer, so that a run that stops early
//! still says how far it got (the load it reached, its iterations, GMRES iterations and
//! force evaluations), and the note that names why it stopped in the units of the load.

use std::time::Instant;

use crate::study::{Failure, Outcome, Variant};
use crate::verdict::{Verdict, classify};
use bs_dr::{LoadFailure, Progress, SolveError};
use bs_scene::Prepared;

use super::Cell;

/// What a measured run cost and where it ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metrics {
    /// Newton iterations (Newton–Krylov) or DR steps, including those of a run that stopped.
    pub steps: usize,
    /// GMRES iterations (Newton–Krylov; 0 for DR).
    pub linear: usize,
    /// Internal-force evaluations.
    pub force_evaluations: usize,
    /// Solver and final contact check (converged runs; `Outcome::solve_seconds`).
    pub solve_seconds: Option<f64>,
    /// The whole variant: setup, preparation (the preconditioner) and solve, or until it
    /// stopped.
    pub wall_seconds: f64,
    /// Smallest element volume ratio of the result (converged runs).
    pub min_j: Option<f64>,
    /// Slave nodes on the skull at the end (converged runs).
    pub in_contact: Option<usize>,
}

/// A run with the last progress its observer saw.
#[derive(Debug)]
pub struct Measured {
    /// The result.
    pub result: Result<Outcome, Failure>,
    /// The last step or iteration reported (none if it stopped before the first).
    pub last: Option<Progress>,
    /// Wall time of the whole variant (seconds).
    pub wall_seconds: f64,
}

/// Solves `scene` with `variant`, keeping the last progress report.
pub fn measure(variant: &Variant, scene: &Prepared) -> Measured {
    let mut last = None;
    let started = Instant::now();
    let result = variant.solve_observed(scene, &mut |p| last = Some(*p));
    Measured { result, last, wall_seconds: started.elapsed().as_secs_f64() }
}

impl Measured {
    /// The run's metrics.
    pub fn metrics(&self) -> Metrics {
        let ok = self.result.as_ref().ok();
        Metrics {
            steps: ok.map_or_else(|| self.last.map_or(0, |p| p.step), |o| o.steps),
            linear: ok.map_or_else(
                || self.last.map_or(0, |p| p.linear_iterations),
                |o| o.linear_iterations,
            ),
            force_evaluations: ok.map_or_else(
                || self.last.map_or(0, |p| p.force_evaluations),
                |o| o.force_evaluations,
            ),
            solve_seconds: ok.map(|o| o.solve_seconds),
            wall_seconds: self.wall_seconds,
            min_j: ok.map(|o| o.min_volume_ratio),
            in_contact: ok.map(|o| o.nodes_in_contact),
        }
    }

    /// Why the run stopped, in the load's units (`load` is the full prescribed displacement
    /// in mm, when the row has one): the fraction reached and the cause. Empty for a
    /// converged run.
    pub fn stop_note(&self, load: Option<f64>) -> String {
        let Err(failure) = &self.result else { return String::new() };
        let at = |lambda: f64| match load {
            Some(l) => format!("{:.1} of {l:.0} mm", lambda * l),
            None => format!("{:.1} % of the load", 100.0 * lambda),
        };
        let level = self.last.map(|p| p.load_factor);
        match failure {
            Failure::Solve(SolveError::LoadNotCarried { reached, load: size, cause, fallback }) => {
                let cause = match cause {
                    LoadFailure::WouldInvert { element_id, .. } => {
                        format!("element {element_id} would invert")
                    }
                    LoadFailure::Stalled { changes } => {
                        format!("residual stalled, {changes} contact nodes changing")
                    }
                    LoadFailure::Budget { iterations } => {
                        format!("level budget of {iterations} iterations spent")
                    }
                    LoadFailure::Exhausted { iterations } => {
                        format!("solve budget of {iterations} iterations spent")
                    }
                };
                let fallback = match fallback {
                    Some(f) => format!("; DR fallback: {f}"),
                    None => String::new(),
                };
                format!("reached {:.1} of {size:.0} mm: {cause}{fallback}", reached * size)
            }
            Failure::Solve(SolveError::NoConvergence { steps, .. }) => match level {
                Some(l) => {
                    format!("{steps} iterations spent, at load {} (level in progress)", at(l))
                }
                None => format!("{steps} iterations spent"),
            },
            Failure::Solve(SolveError::ElementInverted { step, element_id, .. }) => match level {
                Some(l) => format!("element {element_id} at step {step}, load {}", at(l)),
                None => format!("element {element_id} at step {step}"),
            },
            Failure::Solve(e) => e.step().map_or(String::new(), |s| format!("at step {s}")),
            Failure::Check(e) => e.to_string(),
            Failure::Setup(e) => e.clone(),
        }
    }
}

/// A cell with its metrics: `note` for a converged run, the stop note otherwise.
pub fn measured_cell(
    row: &str,
    value: String,
    m: &Measured,
    load: Option<f64>,
    note: String,
) -> Cell {
    let tol = 1e-3;
    let verdict = classify(&m.result, tol);
    let metrics = m.metrics();
    let note = if m.result.is_ok() { note } else { m.stop_note(load) };
    let c = Cell {
        row: row.into(),
        value,
        verdict,
        steps: m.result.as_ref().map_or(0, |o| o.steps),
        note,
        ablation: false,
        metrics: Some(metrics),
    };
    println!(
        "{:<44} {:<12} {:<24} {:>5} steps {:>6} GMRES {:>7.2} s  {}",
        c.row,
        c.value,
        Verdict::text(&c.verdict),
        metrics.steps,
        metrics.linear,
        metrics.solve_seconds.unwrap_or(metrics.wall_seconds),
        c.note
    );
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stopped(e: SolveError, load_factor: f64) -> Measured {
        let last = Progress {
            step: 7,
            err: 1.0,
            rho: 0.0,
            load_factor,
            max_displacement: 1.0,
            contact: Default::default(),
            linear_iterations: 70,
            force_evaluations: 90,
        };
        Measured { result: Err(Failure::Solve(e)), last: Some(last), wall_seconds: 2.0 }
    }

    /// The note gives the fraction reached in mm and the cause; the metrics of a run that
    /// stopped are its last progress report's.
    #[test]
    fn stop_notes_name_the_load_reached_and_the_cause() {
        let m = stopped(
            SolveError::LoadNotCarried {
                reached: 0.905,
                load: 40.0,
                cause: LoadFailure::WouldInvert { element: 1233, element_id: 1234 },
                fallback: None,
            },
            0.95,
        );
        assert_eq!(m.stop_note(Some(40.0)), "reached 36.2 of 40 mm: element 1234 would invert");
        let k = m.metrics();
        assert_eq!((k.steps, k.linear, k.force_evaluations), (7, 70, 90));
        assert_eq!((k.solve_seconds, k.min_j, k.wall_seconds), (None, None, 2.0));
        let m = stopped(SolveError::NoConvergence { err: 0.1, steps: 200, tolerance: 1e-3 }, 0.453);
        assert_eq!(
            m.stop_note(Some(40.0)),
            "200 iterations spent, at load 18.1 of 40 mm (level in progress)"
        );
        let m = stopped(
            SolveError::ElementInverted { step: 925, element: 1, element_id: 2, jacobian: -0.1 },
            0.25,
        );
        assert_eq!(m.stop_note(None), "element 2 at step 925, load 25.0 % of the load");
    }
}
