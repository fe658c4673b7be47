//! `cargo xtask stability trace`: Dynamic Relaxation's path on a scene, step by step — the
//! prescribed displacement reached, the fictitious kinetic energy, the largest step and the
//! smallest element volume ratio `J` — and its state where the push reaches a given depth
//! against Newton–Krylov's equilibrium at that depth. What tells an element that cannot
//! carry the load (small `J` at equilibrium) from a path that overshoots (small `J` on the
//! way, with kinetic energy, while the equilibrium is healthy).

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::study::Variant;
use bs_dr::{DrParams, DynamicRelaxation, Progress};
use bs_mesh::Vector3;
use bs_scene::Prepared;
use bs_scene::compose::compose;
use bs_scene::scene::SolverKind;

/// What the command was asked.
/// What to trace.
#[derive(Debug, Clone)]
pub struct Options {
    pub scene: PathBuf,
    /// The push to trace, mm (the scene's prescribed displacements scaled to it).
    pub load: Option<f64>,
    /// DR's load ramp, steps (the scene's when none).
    pub ramp: Option<usize>,
    /// A row every this many steps.
    pub every: usize,
    /// The depth (mm) at which DR's state is compared with Newton–Krylov's equilibrium.
    pub at: Option<f64>,
    /// Where the rows go as CSV.
    pub out: Option<PathBuf>,
}

/// One traced step.
#[derive(Debug, Clone, Copy)]
struct Row {
    step: usize,
    /// Prescribed displacement reached (mm).
    push: f64,
    /// `½ Σ m |Δu|²` with the reference fictitious masses (pseudo time step 1).
    kinetic: f64,
    max_step: f64,
    min_j: f64,
}

/// The trace and DR's state where the push first reached `at`.
#[derive(Debug)]
struct Traced {
    rows: Vec<Row>,
    state_at: Option<Vec<Vector3<f64>>>,
    outcome: String,
}

fn trace(p: &Prepared, a: &Options, scale: f64) -> Result<Traced, String> {
    let mut c = compose(p).map_err(|e| e.to_string())?;
    let model = &c.model;
    let mut masses = vec![0.0; model.node_count()];
    let params = DrParams {
        tolerance: p.scene.solver.tolerance,
        tolerance_unit: bs_dr::ToleranceUnit::Length,
        ramp_steps: a.ramp.unwrap_or(p.scene.solver.ramp_steps),
        ..DrParams::default()
    };
    model.dr_masses_into(params.step_fraction, &mut masses);
    let mut contact = c.contact.take();
    let mut none = bs_dr::NoContact;
    let contact: &mut dyn bs_dr::Contact = match &mut contact {
        Some(sc) => sc,
        None => &mut none,
    };
    let (mut rows, mut prev, mut state_at) = (vec![], vec![Vector3::zeros(); masses.len()], None);
    let mut watch = |pr: &Progress, u: &[Vector3<f64>]| {
        let push = pr.load_factor * scale;
        if a.at.is_some_and(|at| push >= at) && state_at.is_none() {
            state_at = Some(u.to_vec());
        }
        if pr.step.is_multiple_of(a.every) || pr.step == 1 {
            let kinetic = 0.5
                * u.iter()
                    .zip(&prev)
                    .zip(&masses)
                    .map(|((x, y), m)| m * (x - y).norm_squared())
                    .sum::<f64>();
            let max_step = u.iter().zip(&prev).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max);
            let min_j = model.min_volume_ratio(u);
            rows.push(Row { step: pr.step, push, kinetic, max_step, min_j });
        }
        prev.copy_from_slice(u);
    };
    let dr = DynamicRelaxation::new(params);
    let result = dr.solve(bs_dr::Problem {
        watch: Some(&mut watch),
        ..bs_dr::Problem::new(model, &c.loads, contact, &mut |_| {})
    });
    let outcome = match result {
        Ok(s) => format!("converged in {} steps", s.report.steps),
        Err(e) => e.to_string(),
    };
    Ok(Traced { rows, state_at, outcome })
}

fn csv(rows: &[Row]) -> String {
    let mut s = String::from("step,push_mm,kinetic_energy,max_step_mm,min_J\n");
    for r in rows {
        let _ = writeln!(
            s,
            "{},{:.6},{:.6e},{:.6e},{:.6}",
            r.step, r.push, r.kinetic, r.max_step, r.min_j
        );
    }
    s
}

/// `cargo xtask stability trace …`.
pub fn main(a: &Options) -> Result<(), String> {
    let p = Prepared::load(&a.scene).map_err(|e| format!("{}: {e}", a.scene.display()))?;
    let c0 = compose(&p).map_err(|e| e.to_string())?;
    let scene_push = bs_dr::load_scale(&c0.model, &c0.loads);
    let factor = a.load.map_or(1.0, |l| l / scene_push);
    let p = Variant { load_factor: Some(factor), ..Variant::default() }
        .apply(&p)
        .map_err(|e| format!("{e:?}"))?;
    let scale = scene_push * factor;
    let t = trace(&p, a, scale)?;
    if let Some(out) = &a.out {
        std::fs::write(out, csv(&t.rows)).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    for r in t.rows.iter().step_by((t.rows.len() / 20).max(1)).chain(t.rows.last()) {
        println!(
            "step {:>6}  push {:>6.2} mm  kinetic {:>10.3e}  max step {:>8.2e} mm  min J {:.4}",
            r.step, r.push, r.kinetic, r.max_step, r.min_j
        );
    }
    println!("DR: {}", t.outcome);
    let (Some(at), Some(state)) = (a.at, &t.state_at) else { return Ok(()) };
    let v = Variant {
        load_factor: Some(at / scene_push),
        solver: Some(SolverKind::NewtonKrylov),
        max_steps: Some(1000),
        ..Variant::default()
    };
    let base = Prepared::load(&a.scene).map_err(|e| e.to_string())?;
    match v.solve_observed(&base, &mut |_| {}) {
        Ok(nk) => {
            let d: Vec<f64> =
                nk.displacements.iter().zip(state).map(|(x, y)| (x - y).norm()).collect();
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            let max = d.iter().copied().fold(0.0, f64::max);
            println!(
                "at {at} mm: DR's state on the ramp has min J {:.4}; Newton-Krylov's equilibrium \
                 min J {:.4}; they differ by {mean:.3} mm mean, {max:.3} mm max",
                c0.model.min_volume_ratio(state),
                nk.min_volume_ratio
            );
        }
        Err(e) => println!("at {at} mm: Newton-Krylov did not converge: {e:?}"),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_csv_has_one_row_per_traced_step() {
        let r = Row { step: 7, push: 1.5, kinetic: 2.0, max_step: 0.25, min_j: 0.5 };
        let text = csv(&[r, Row { step: 8, ..r }]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "step,push_mm,kinetic_energy,max_step_mm,min_J");
        assert_eq!(lines[1], "7,1.500000,2.000000e0,2.500000e-1,0.500000");
        assert_eq!(lines.len(), 3);
    }
}
