//! `brainshift run SCENE`: solve a scene ([`bs_scene::Run`]) with progress on the terminal
//! and write result.vtu, displacements.csv and report.json.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use bs_dr::Progress;
use bs_scene::output::{RunContext, report, write_outputs};
use bs_scene::scene::SolverKind;
use bs_scene::{Prepared, Run};

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
    /// Samples of the fit's uncertainty (`None`: not sampled).
    pub uncertainty: Option<usize>,
    /// The grid of uncertainty.nii.gz (an image; `None`: around the deformed brain).
    pub uncertainty_grid: Option<PathBuf>,
    /// GMRES's relative residual per sample (`None`: the default, 1e-2).
    pub uncertainty_tolerance: Option<f64>,
}

/// `--uncertainty N`: a whole number of samples, at least 2.
pub fn parse_samples(s: &str) -> Result<usize, String> {
    match s.trim().parse::<i64>() {
        Ok(n) if n >= 2 => Ok(n as usize),
        Ok(n) => Err(format!(
            "{n} samples: give at least 2 (σ is a root mean square over the samples; 32 give \
             it to about 13 %)"
        )),
        Err(_) => Err(format!("'{s}' is not a whole number of samples (e.g. 32)")),
    }
}

/// `--uncertainty-tolerance R`: a relative residual between 0 and 1.
pub fn parse_tolerance(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(r) if r > 0.0 && r < 1.0 => Ok(r),
        Ok(r) => Err(format!(
            "{r}: give a relative residual between 0 and 1 (1e-2 by default; 1e-3 for σ \
             within about 1 % of its converged value)"
        )),
        Err(_) => Err(format!("'{s}' is not a number (e.g. 1e-3)")),
    }
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

/// Set by SIGINT or SIGTERM; the solve stops at its next step.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Exit status of an interrupted run (128 + SIGINT, the shell's convention).
const INTERRUPTED_EXIT: i32 = 130;

/// Catches SIGINT and SIGTERM so that an interrupted run stops between steps, says where it
/// was and exits before anything is written (outputs are written only after a verified
/// solve, each atomically).
fn catch_interrupts() {
    // A second handler cannot be installed (e.g. in-process tests): the default (the
    // process ends, nothing written yet) is then kept.
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::SeqCst));
}

fn stop_if_interrupted(what: &str) {
    if INTERRUPTED.load(Ordering::SeqCst) {
        eprintln!("interrupted {what}; nothing written");
        std::process::exit(INTERRUPTED_EXIT);
    }
}

/// Sets up `--threads N` worker threads (all cores when `None`).
pub fn init_threads(threads: Option<usize>) -> Result<(), String> {
    if let Some(n) = threads {
        if n == 0 {
            return Err("--threads 0: give at least 1 worker thread (or leave --threads out \
                        to use all cores)"
                .into());
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| format!("cannot start {n} threads: {e}"))?;
    }
    Ok(())
}

/// Runs a scene end to end.
pub fn run(opts: &RunOptions) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let started = Instant::now();
    init_threads(opts.threads)?;
    catch_interrupts();
    let prepared = Prepared::load(&opts.scene)?;
    let mut run = Run::prepare(prepared)?;
    stop_if_interrupted("during preparation");
    if opts.uncertainty.is_some() {
        bs_scene::uncertainty::check(&run)?;
        if let Some(g) = &opts.uncertainty_grid
            && !g.is_file()
        {
            return Err(format!(
                "--uncertainty-grid {}: no such image (give the pre-operative image whose \
                 grid the σ volume takes, or leave it out for a 1 mm grid around the brain)",
                g.display()
            )
            .into());
        }
    }
    let threads = rayon::current_num_threads();
    let (p, c) = (&run.prepared, &run.composed);
    if !opts.quiet {
        for w in &p.warnings {
            eprintln!("warning: {w}");
        }
        let (tets, hexes) = p.mesh.count_by_kind();
        eprintln!(
            "brainshift: {} nodes, {} elements ({}), {} slave nodes, solver {}, {} thread{}",
            p.mesh.nodes.len(),
            tets + hexes,
            p.element.name(),
            c.slaves.len(),
            p.scene.solver.kind.name(),
            threads,
            if threads == 1 { "" } else { "s" }
        );
        for line in load_lines(p) {
            eprintln!("{line}");
        }
    }
    let every = if run.settings.kind == SolverKind::Dr { 50 } else { 1 };
    let mut reporter = Reporter::new(opts.quiet, run.settings.tolerance, every);
    let solved = run.solve(&mut |pr| {
        if INTERRUPTED.load(Ordering::SeqCst) {
            reporter.finish();
            stop_if_interrupted(&format!(
                "at step {} (load {:.1} %, error estimate {:.3e}, tolerance {:.1e})",
                pr.step,
                100.0 * pr.load_factor,
                pr.err,
                reporter.tolerance
            ));
        }
        reporter.update(pr)
    });
    reporter.finish();
    let mut solved = solved?;
    let sigma_image = match opts.uncertainty {
        Some(n) => {
            let to = (opts.out.as_path(), opts.uncertainty_grid.as_deref(), opts.quiet);
            let how = (n, opts.uncertainty_tolerance);
            Some(crate::uncertainty::sample(&mut run, &mut solved, how, to)?)
        }
        None => None,
    };
    let ctx = RunContext { total_seconds: started.elapsed().as_secs_f64(), threads };
    let mut report = report(&run, &solved, ctx);
    let written = write_outputs(&opts.out, &run.prepared, &solved, &report)?;
    let sigma_file = opts.out.join(crate::uncertainty::UNCERTAINTY_NII);
    match &sigma_image {
        Some(image) => image.write(&sigma_file)?,
        None if sigma_file.is_file() => std::fs::remove_file(&sigma_file)?,
        None => {}
    }
    report.total_seconds = started.elapsed().as_secs_f64();
    if !opts.quiet {
        let u_unit = run.prepared.scene.units.symbol();
        crate::emit(&format!(
            "converged in {} {} ({:.3} s preparation, {:.3} s solve of which {:.3} s contact, \
             {:.3} s total): error estimate {:.2e} {u_unit}, max displacement {:.4} {u_unit}, {} \
             nodes in contact, max penetration before correction {:.2e} {u_unit}; verified: min J \
             {:.3}, equilibrium residual {:.1e} (bound {:.1e})\n{}wrote {}, {}, {}, {}{}{}{}\n",
            report.steps,
            if run.prepared.scene.solver.kind == bs_scene::scene::SolverKind::Dr {
                "steps"
            } else {
                "iterations"
            },
            report.prepare_seconds,
            report.solve_seconds,
            report.contact_seconds,
            report.total_seconds,
            report.error_estimate,
            report.max_displacement,
            report.nodes_in_contact,
            report.max_penetration_before_correction,
            report.min_jacobian,
            report.equilibrium_residual,
            report.equilibrium_bound,
            report
                .measurements
                .iter()
                .enumerate()
                .map(|(i, m)| measurement_line(i, m, u_unit) + "\n")
                .chain(report.gravity.as_ref().and_then(|g| estimate_line(g, u_unit)))
                .chain(unused_line(&report))
                .collect::<String>(),
            written.vtu.display(),
            written.vtk.display(),
            written.csv.display(),
            written.report.display(),
            written.skull.as_ref().map(|s| format!(", {}", s.display())).unwrap_or_default(),
            written
                .surfaces
                .iter()
                .map(|(_, vtk, stl)| format!(", {}, {}", vtk.display(), stl.display()))
                .collect::<String>(),
            written.residuals.as_ref().map(|r| format!(", {}", r.display())).unwrap_or_default(),
        ));
        if let (Some(u), Some(path)) = (&report.uncertainty, &written.uncertainty) {
            crate::emit(&format!(
                "{}; wrote {}, {}\n",
                crate::uncertainty::line(u, u_unit),
                path.display(),
                sigma_file.display()
            ));
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The line saying the measurements were not used and why, unless the estimate's line says
/// it.
fn unused_line(report: &bs_scene::output::RunReport) -> Option<String> {
    let estimated = report.gravity.as_ref().is_some_and(|g| !g.estimates.is_empty());
    let why = report.data_unused.as_ref().filter(|_| !estimated)?;
    Some(format!("the measurements were not used: {why}\n"))
}

/// The line on gravity's estimated parameters (none without `[gravity] estimate`).
fn estimate_line(g: &bs_scene::estimate::GravityReport, u_unit: &str) -> Option<String> {
    if g.estimates.is_empty() {
        return None;
    }
    let data = if g.data_used { "" } else { "; the data were not used" };
    let note = g.note.as_ref().map_or(String::new(), |n| format!(" ({n})"));
    let from = match (g.inliers, g.landmark_inliers) {
        (n, 0) => format!("{n} scan points"),
        (0, l) => format!("{l} landmarks"),
        (n, l) => format!("{n} scan points and {l} landmarks"),
    };
    Some(format!(
        "gravity estimated from {from} in {} Gauss-Newton iterations ({} solves): {}{data}{note}\n",
        g.iterations,
        g.solves,
        g.summary(u_unit)
    ))
}

/// One line each on the scene's gravity and resection (none without).
pub fn load_lines(p: &Prepared) -> Vec<String> {
    let mut lines = Vec::new();
    if let Some(g) = &p.scene.gravity {
        let [x, y, z] = g.direction;
        let fluid = g.fluid.map_or(String::new(), |f| {
            let [a, b, c] = f.level;
            format!("; fluid {} kg/m³ below the level through ({a}, {b}, {c})", f.density)
        });
        lines.push(format!(
            "gravity: direction ({x}, {y}, {z}) in the scene's frame, {} m/s²{fluid}",
            g.acceleration
        ));
    }
    if let Some(r) = &p.resection {
        let pressure = r.walls.iter().map(|w| w.1).fold(0.0, f64::max);
        lines.push(format!(
            "resected {}: {} elements removed, {} cavity wall triangles free (pressure up to {} \
             Pa), {} nodes left in no element held",
            r.regions.join(", "),
            r.elements,
            r.walls.len(),
            pressure,
            r.orphans.len()
        ));
    }
    lines
}

/// One line on what the fit of measurement `i` did.
pub fn measurement_line(i: usize, m: &bs_scene::measure::MeasurementReport, u: &str) -> String {
    let rigid = m.rigid.as_ref().map_or(String::new(), |r| {
        let t = r.translation;
        format!(
            "; rigid correction {:.2} {u} and {:.2} degrees from {} bone points (RMS {:.2} -> \
             {:.2} {u})",
            (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt(),
            r.angle_degrees,
            r.bone_inliers,
            r.bone_rms_before,
            r.bone_rms_after
        )
    });
    if m.kind == bs_scene::measure::MeasurementKind::Landmarks {
        let through = match m.nset.as_str() {
            "" => "as evidence for gravity's unknowns".to_string(),
            set => format!("through {set}"),
        };
        return format!(
            "[[measurement]] #{} landmarks {} {through}: {} of {} pairs inliers ({} outliers), \
             residual RMS {:.3} {u} (max {:.3}) after {} model solves; the landmarks moved up to \
             {:.3} {u} (mean {:.3})",
            i + 1,
            m.file,
            m.inliers,
            m.points,
            m.outliers,
            m.rms_residual,
            m.max_residual,
            m.solves,
            m.max_pull,
            m.mean_pull
        );
    }
    let sliding = m.sag_direction.map_or("; sliding free".to_string(), |d| {
        format!(
            "; sliding resisted across the sag direction ({:.2}, {:.2}, {:.2})",
            d[0], d[1], d[2]
        )
    });
    format!(
        "[[measurement]] #{} {} on {}: {} of {} points inliers ({} outliers, {} on the patch \
         border, {} farther than max_distance), residual RMS {:.3} {u} (max {:.3}); the data \
         moved the surface up to {:.3} {u} (mean {:.3}){sliding}{rigid}",
        i + 1,
        m.file,
        m.nset,
        m.inliers,
        m.points,
        m.outliers,
        m.border,
        m.far,
        m.rms_residual,
        m.max_residual,
        m.max_pull,
        m.mean_pull
    )
}

/// The bundled default scene (the real-anatomy fixture) for `demo` and a bare `run`.
pub fn default_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/mni152/scene.toml")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate's line names the data it came from: scan points, landmarks, or both.
    #[test]
    fn the_estimate_line_names_the_data_it_came_from() {
        let mut g = bs_scene::estimate::GravityReport::of(&bs_scene::scene::Gravity {
            direction: [0.0, 0.0, -1.0],
            acceleration: 9.81,
            fluid: None,
            estimate: None,
        });
        assert_eq!(estimate_line(&g, "mm"), None);
        g.estimates.push(bs_scene::estimate::ParameterEstimate {
            name: "level".into(),
            estimate: 9.6,
            standard_error: 0.4,
            prior: 15.0,
            determined: true,
        });
        let line = |g: &bs_scene::estimate::GravityReport| estimate_line(g, "mm").unwrap();
        (g.inliers, g.landmark_inliers) = (591, 0);
        assert!(line(&g).starts_with("gravity estimated from 591 scan points in "), "{}", line(&g));
        (g.inliers, g.landmark_inliers) = (0, 15);
        assert!(line(&g).starts_with("gravity estimated from 15 landmarks in "), "{}", line(&g));
        (g.inliers, g.landmark_inliers) = (591, 15);
        assert!(line(&g).contains("from 591 scan points and 15 landmarks in "), "{}", line(&g));
        assert!(line(&g).contains("level 9.60 ± 0.40 mm"), "{}", line(&g));
    }
}
