//! `brainshift run SCENE`: solve a scene and write result.vtu, displacements.csv and
//! report.json.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use bs_dr::{DrParams, Progress};
use bs_mesh::io::{Field, Fields, write_atomic};
use serde::Serialize;

use crate::check::{CheckError, Prepared};
use crate::compose::{Composed, compose};
use crate::study::{SolveSettings, final_contact, prepare_solver, solve_composed};

/// Options of `run`.
#[derive(Debug)]
pub struct RunOptions {
    /// The scene file.
    pub scene: PathBuf,
    /// Output folder.
    pub out: PathBuf,
    /// Worker threads (default: all cores).
    pub threads: Option<usize>,
    /// No progress output.
    pub quiet: bool,
}

/// The machine-readable summary written to report.json.
#[derive(Debug, Serialize)]
pub struct RunReport {
    /// Always true in a written report: a failed run writes no report.
    pub converged: bool,
    /// DR steps or Newton iterations.
    pub steps: usize,
    /// Wall time of the solver alone.
    pub wall_seconds: f64,
    /// Wall time of everything that depends only on mesh, materials and skull (the model's
    /// precomputation, the contact search structures, the solver's preconditioner): what can
    /// be computed before surgery.
    pub prepare_seconds: f64,
    /// Wall time from known displacements to a converged, checked result (the solver and
    /// the final contact check).
    pub solve_seconds: f64,
    /// Evaluations of the internal forces.
    pub force_evaluations: usize,
    /// Inner linear-solver iterations (newton-krylov: GMRES; otherwise 0).
    pub linear_iterations: usize,
    /// Part of `wall_seconds` spent in contact enforcement and queries.
    pub contact_seconds: f64,
    /// Part of `wall_seconds` spent evaluating internal forces (newton-krylov; 0 for the
    /// others, which do not time it).
    pub force_seconds: f64,
    /// Part of `wall_seconds` spent in the preconditioner (newton-krylov).
    pub preconditioner_seconds: f64,
    /// Wall time including reading, setup and writing.
    pub total_seconds: f64,
    /// Final error estimate (mesh length units).
    pub error_estimate: f64,
    /// Tolerance it met (mesh length units).
    pub tolerance: f64,
    /// Physical critical time step of the mesh times the step fraction, in seconds. DR uses
    /// fictitious masses, so this is the step the explicit dynamics would need.
    pub time_step: f64,
    /// Slave nodes lying on the skull at the end (within the tolerance).
    pub nodes_in_contact: usize,
    /// Largest distance by which any slave was found outside the skull in any step, before
    /// it was moved back (mesh length units).
    pub max_penetration_before_correction: f64,
    /// Largest distance of any slave outside the skull in the written result.
    pub max_penetration_after: f64,
    /// Largest nodal displacement magnitude.
    pub max_displacement: f64,
    /// `"newton-krylov"`, `"dr"` or `"newton"`.
    pub solver: &'static str,
    /// `"t4"`, `"t4anp"` or `"h8"`.
    pub element: String,
    /// Contact handler, or `"none"`.
    pub algorithm: String,
    /// Counts.
    pub nodes: usize,
    /// Counts.
    pub elements: usize,
    /// Slave (contact candidate) nodes.
    pub slave_nodes: usize,
    /// Threads used.
    pub threads: usize,
    /// Length unit of all lengths in this report.
    pub units: &'static str,
}

/// Progress display: a spinner on a terminal, a plain line every few seconds otherwise.
struct Reporter {
    bar: Option<indicatif::ProgressBar>,
    quiet: bool,
    last: Instant,
    tolerance: f64,
    /// Report every `every`-th step (50 for DR's thousands of steps, 1 for Newton's tens).
    every: usize,
}

impl Reporter {
    fn new(quiet: bool, tolerance: f64, every: usize) -> Self {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = indicatif::ProgressBar::new_spinner();
            b.enable_steady_tick(Duration::from_millis(120));
            b
        });
        Reporter { bar, quiet, last: Instant::now(), tolerance, every }
    }

    fn update(&mut self, p: &Progress) {
        if self.quiet || !p.step.is_multiple_of(self.every) {
            return;
        }
        let msg = format!(
            "step {:>7}  load {:>5.1}%  error estimate {:.3e} (tolerance {:.1e})  max |u| {:.4}  contact {}",
            p.step,
            100.0 * p.load_factor,
            p.err,
            self.tolerance,
            p.max_displacement,
            p.contact.nodes_in_contact
        );
        match &self.bar {
            Some(b) => b.set_message(msg),
            None if self.last.elapsed() >= Duration::from_secs(2) => {
                self.last = Instant::now();
                eprintln!("{msg}");
            }
            None => {}
        }
    }

    fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// Runs a scene end to end.
pub fn run(opts: &RunOptions) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let started = Instant::now();
    let with_scene = |e: CheckError| format!("{}: {e}", opts.scene.display());
    let prepared = Prepared::load(&opts.scene)?;
    if let Some(n) = opts.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .map_err(|e| format!("cannot start {n} threads: {e}"))?;
    }
    let preparing = Instant::now();
    let mut composed = compose(&prepared).map_err(with_scene)?;
    composed.check_initial_gap(&prepared).map_err(with_scene)?;
    let settings = SolveSettings::of(&prepared);
    prepare_solver(&mut composed, &settings)
        .map_err(|e| format!("cannot prepare the solver: {e}"))?;
    let prepare_seconds = preparing.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    if !opts.quiet {
        for w in &prepared.warnings {
            eprintln!("warning: {w}");
        }
        let (tets, hexes) = prepared.mesh.count_by_kind();
        eprintln!(
            "brainshift: {} nodes, {} elements ({}), {} slave nodes, solver {:?}, {} thread{}",
            prepared.mesh.nodes.len(),
            tets + hexes,
            element_name(&prepared),
            composed.slaves.len(),
            prepared.scene.solver.kind,
            threads,
            if threads == 1 { "" } else { "s" }
        );
    }

    let solving = Instant::now();
    let solution = solve(&prepared, &mut composed, opts.quiet)?;
    let (in_contact, max_penetration_after) = final_contact(
        &prepared,
        &composed,
        &solution.solution.displacements,
        prepared.scene.solver.tolerance,
    )?;
    let times =
        Times { started, prepare_seconds, solve_seconds: solving.elapsed().as_secs_f64(), threads };
    write_outputs(&prepared, &composed, &solution, opts, &times, in_contact, max_penetration_after)
}

fn element_name(p: &Prepared) -> String {
    format!("{:?}", p.element).to_lowercase()
}

struct Times {
    started: Instant,
    prepare_seconds: f64,
    solve_seconds: f64,
    threads: usize,
}

struct Solved {
    solution: bs_dr::Solution,
    max_penetration: f64,
}

fn solve(
    p: &Prepared,
    c: &mut Composed,
    quiet: bool,
) -> Result<Solved, Box<dyn std::error::Error>> {
    let settings = SolveSettings::of(p);
    let every = if settings.kind == crate::scene::SolverKind::Dr { 50 } else { 1 };
    let mut reporter = Reporter::new(quiet, settings.tolerance, every);
    let result = solve_composed(c, &settings, &mut |pr| reporter.update(pr));
    reporter.finish();
    let (solution, max_penetration) = result.map_err(|e| format!("the solver stopped: {e}"))?;
    Ok(Solved { solution, max_penetration })
}

fn write_outputs(
    p: &Prepared,
    c: &Composed,
    s: &Solved,
    opts: &RunOptions,
    times: &Times,
    in_contact: Vec<f64>,
    max_penetration_after: f64,
) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let u = &s.solution.displacements;
    let measures = c.model.element_measures(u)?;
    let n = p.mesh.nodes.len();
    let tol = p.scene.solver.tolerance;
    let (started, threads) = (times.started, times.threads);

    std::fs::create_dir_all(&opts.out)
        .map_err(|e| format!("cannot create the output folder {}: {e}", opts.out.display()))?;
    let fields = Fields {
        point: vec![
            Field::new("displacement", 3, u.iter().flat_map(|d| [d.x, d.y, d.z]).collect()),
            Field::new("in_contact", 1, in_contact.clone()),
        ],
        cell: vec![
            Field::new("von_mises", 1, measures.von_mises.clone()),
            Field::new("J", 1, measures.volume_ratio.clone()),
        ],
    };
    let vtu = opts.out.join("result.vtu");
    bs_mesh::io::write_mesh(&vtu, &p.mesh, &fields)?;

    let csv = opts.out.join("displacements.csv");
    write_atomic(&csv, |w| {
        writeln!(w, "node_id,ux,uy,uz")?;
        for (id, d) in p.mesh.node_ids.iter().zip(u) {
            writeln!(w, "{id},{:?},{:?},{:?}", d.x, d.y, d.z)?;
        }
        Ok(())
    })?;

    let r = &s.solution.report;
    let (dt, _) = c.model.critical_time_step();
    let report = RunReport {
        converged: true,
        steps: r.steps,
        wall_seconds: r.elapsed.as_secs_f64(),
        prepare_seconds: times.prepare_seconds,
        solve_seconds: times.solve_seconds,
        force_evaluations: r.force_evaluations,
        linear_iterations: r.linear_iterations,
        contact_seconds: c.contact.as_ref().map_or(0.0, |sc| sc.elapsed.as_secs_f64()),
        force_seconds: r.breakdown.forces.as_secs_f64(),
        preconditioner_seconds: r.breakdown.preconditioner.as_secs_f64(),
        total_seconds: started.elapsed().as_secs_f64(),
        error_estimate: r.err,
        tolerance: tol,
        time_step: dt * DrParams::default().step_fraction * p.scene.units.metres(),
        nodes_in_contact: in_contact.iter().filter(|&&x| x > 0.0).count(),
        max_penetration_before_correction: s.max_penetration,
        max_penetration_after,
        max_displacement: u.iter().map(|d| d.norm()).fold(0.0, f64::max),
        solver: p.scene.solver.kind.name(),
        element: element_name(p),
        algorithm: p.scene.contact.as_ref().map_or("none", |c| c.algorithm.name()).to_string(),
        nodes: n,
        elements: p.mesh.elements.len(),
        slave_nodes: c.slaves.len(),
        threads,
        units: p.scene.units.symbol(),
    };
    let json = serde_json::to_string_pretty(&report)?;
    write_atomic(&opts.out.join("report.json"), |w| writeln!(w, "{json}"))?;

    if !opts.quiet {
        let u_unit = p.scene.units.symbol();
        crate::emit(&format!(
            "converged in {} {} ({:.3} s preparation, {:.3} s solve of which {:.3} s contact, \
             {:.3} s total): error estimate {:.2e} {u_unit}, max displacement {:.4} {u_unit}, {} \
             nodes in contact, max penetration before correction {:.2e} {u_unit}\nwrote {}, {}, {}\n",
            report.steps,
            if report.solver == "dr" { "steps" } else { "iterations" },
            report.prepare_seconds,
            report.solve_seconds,
            report.contact_seconds,
            report.total_seconds,
            report.error_estimate,
            report.max_displacement,
            report.nodes_in_contact,
            report.max_penetration_before_correction,
            vtu.display(),
            csv.display(),
            opts.out.join("report.json").display()
        ));
    }
    Ok(ExitCode::SUCCESS)
}

/// The bundled default scene (the real-anatomy fixture) for `demo` and a bare `run`.
pub fn default_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/mni152/scene.toml")
}
