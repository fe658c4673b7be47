//! `cargo xtask fit`: the measurement-fit fixture and study (the truth and its scans in
//! [`truth`], the grid of fits in [`study`], its figure in [`chart`], the landmark cases in
//! [`landmarks`]).
//!
//! * `fit fixture` writes `fixtures/fit/` (the truth, one scan of the first target case as
//!   .csv and .ply, its scene);
//! * `fit study [--quick]` runs the grid and writes the table and the chart of `docs/fit.md`;
//! * `fit gravity [--quick]` fits scans of gravity-driven truths with gravity known, off and
//!   estimated ([`gravity`]) and writes its table in `docs/fit.md`;
//! * `fit gravity-fixture` writes `fixtures/fit-gravity/` (a gravity truth, its scan, the
//!   fit estimating level and direction, and that scene's forward solve).

mod calibration_chart;
mod chart;
mod gravity;
mod landmarks;
mod study;
mod truth;
mod uncertainty;

use std::fmt::Write as _;
use std::time::Instant;

use bs_mesh::Vector3;

use crate::util::root;
use truth::{Case, deep_error, regions, solve, truth, write_scan};

/// `cargo xtask fit fixture`.
pub fn fixture() -> Result<(), String> {
    let dir = root().join("fixtures/fit");
    let started = Instant::now();
    let t = truth(&dir, "../mni152-regions")?;
    let case = Case::target();
    let text = write_scan(&t, &case, &dir, "../mni152-regions")?;
    // Held-out landmarks for `--uncertainty` (the calibration study's: 15 pairs, 0.5 mm).
    let pairs = landmarks::pairs(&t, uncertainty::HELD_OUT, uncertainty::HELD_OUT_SIGMA, 1047);
    landmarks::write_pairs(&dir.join("held-out.csv"), &pairs)?;
    let text = format!(
        "{text}\n# Landmark pairs the fit does not see (15, 5–25 mm under the window, 0.5 mm noise):\n\
         # with --uncertainty they scale σ where they miss by more than it predicts.\n\
         [uncertainty]\nheld_out = \"held-out.csv\"\nsigma = {:?}\n",
        uncertainty::HELD_OUT_SIGMA
    );
    crate::util::write(&dir.join("scene.toml"), &text)?;
    // The same scan as a PLY file (for the test that both give the same answer).
    let points =
        bs_mesh::io::points::read_points(&dir.join("scan.csv")).map_err(|e| e.to_string())?;
    let mut ply = Vec::new();
    bs_mesh::io::ply::write(&mut ply, &points).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("scan.ply"), ply).map_err(|e| e.to_string())?;
    let s = solve(&dir.join("scene.toml"))?;
    let (mean, p95, max) = deep_error(&t, &s.u);
    let none = deep_error(&t, &vec![Vector3::zeros(); s.u.len()]);
    println!(
        "fixtures/fit: {} deep nodes; fit {} iterations, {:.2} s: deep error mean {mean:.3} mm, \
         p95 {p95:.3}, max {max:.3} (no correction: mean {:.3}); {:.1} s in all",
        t.deep.len(),
        s.iterations,
        s.seconds,
        none.0,
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `cargo xtask fit study [--quick]`.
pub fn run_study(quick: bool) -> Result<(), String> {
    let started = Instant::now();
    let dir = root().join("target/fit-study");
    let mesh_dir = regions().display().to_string();
    let t = truth(&dir, &mesh_dir)?;
    let none = deep_error(&t, &vec![Vector3::zeros(); t.u.len()]);
    let mut rows = Vec::new();
    for (group, case) in study::cases(quick) {
        let row = study::fit(&t, group, case, &dir);
        eprintln!(
            "{group}: sigma {} coverage {} outliers {} misalignment {}: {}",
            case.sigma,
            case.coverage,
            case.outliers,
            case.misalignment,
            study::cell(&row.fit)
        );
        rows.push(row);
    }
    let oracles: Vec<_> =
        [1.0, 0.5, 0.25].into_iter().map(|c| (c, study::oracle(&t, c, &dir))).collect();
    let sigmas: &[f64] = if quick { &[1.0] } else { &[0.0, 0.5, 1.0, 2.0] };
    let imposed: Vec<_> = sigmas.iter().map(|&s| (s, study::imposed(&t, s, &dir))).collect();
    let mut doc = study::table(&rows, &oracles, none);
    writeln!(doc, "\nThe same scans imposed node by node (`[[boundary]] surface`, the whole window, noise on the surface's vertices):\n").unwrap();
    writeln!(doc, "| σ (mm) | imposed: deep mean / p95 (mm) |\n|---|---|").unwrap();
    for (s, e) in &imposed {
        writeln!(doc, "| {s} | {} |", study::cell(e)).unwrap();
    }
    let sliding = study::sliding(&t, &dir, quick)?;
    writeln!(doc, "\nThe sliding prior against free sliding (`sliding = \"free\"`), on this truth and on one whose sag is tilted 30° off the window's axis towards +x, where the prior's free direction (the window's mean inward normal) is wrong:\n").unwrap();
    doc += &study::sliding_table(&sliding);
    let counts: &[usize] = if quick { &[15] } else { &[5, 15, 30] };
    let seeds: &[u64] = if quick { &[1000] } else { &[1000, 2000, 3000] };
    let marks: Vec<_> = counts
        .iter()
        .flat_map(|&n| seeds.iter().map(move |&s| (n, s)))
        .map(|(n, s)| landmarks::case(&t, n, 1.0, s, &dir))
        .collect();
    writeln!(doc, "\nLandmark pairs 5–25 mm under the craniotomy (σ = 1 mm per axis; three random draws of each count), fitted through the craniotomy (`[[measurement]] landmarks`, nset = CRANIOTOMY) against today's thin-plate spline of the same pairs imposed on the craniotomy (`[[boundary]] landmarks`, `max_extrapolation = 20`):\n").unwrap();
    doc += &landmarks::table(&marks);
    writeln!(
        doc,
        "\n{} deep nodes of {}; made by `cargo xtask fit study` in {:.0} s (2 threads).",
        t.deep.len(),
        t.mesh.nodes.len(),
        started.elapsed().as_secs_f64()
    )
    .unwrap();
    if quick {
        print!("{doc}");
        return Ok(());
    }
    crate::util::replace_block(&root().join("docs/fit.md"), "fit-study", &doc)?;
    let chart = chart::NoiseChart { rows: &rows, oracles: &oracles, none: none.0 };
    crate::plot::save(&chart, &root().join("docs/charts/fit-noise"), (900, 560))?;
    println!("wrote docs/fit.md and docs/charts/fit-noise.png/.svg");
    Ok(())
}

/// `cargo xtask fit gravity [--quick]`.
pub fn run_gravity(quick: bool) -> Result<(), String> {
    let started = Instant::now();
    let mesh_dir = regions().display().to_string();
    let mut rows = Vec::new();
    for (k, load) in gravity::loads(quick).iter().enumerate() {
        let dir = root().join(format!("target/fit-gravity/{k}"));
        rows.extend(gravity::rows(load, &dir, &mesh_dir)?);
    }
    let mut doc = gravity::table(&rows);
    writeln!(
        doc,
        "
Made by `cargo xtask fit gravity` in {:.0} s (2 threads).",
        started.elapsed().as_secs_f64()
    )
    .unwrap();
    if quick {
        print!("{doc}");
        return Ok(());
    }
    crate::util::replace_block(&root().join("docs/fit.md"), "fit-gravity", &doc)?;
    println!("wrote docs/fit.md");
    Ok(())
}

/// `cargo xtask fit uncertainty [--quick]`: the calibration study of docs/uncertainty.md.
pub fn run_uncertainty(quick: bool) -> Result<(), String> {
    let started = Instant::now();
    let rows = uncertainty::rows(quick)?;
    let mut doc = uncertainty::table(&rows);
    writeln!(
        doc,
        "\n{} samples per σ; made by `cargo xtask fit uncertainty` in {:.0} s (2 threads).",
        uncertainty::SAMPLES,
        started.elapsed().as_secs_f64()
    )
    .unwrap();
    if quick {
        print!("{doc}");
        return Ok(());
    }
    crate::util::replace_block(&root().join("docs/uncertainty.md"), "uncertainty-study", &doc)?;
    let stem = root().join("docs/charts/uncertainty-calibration");
    crate::plot::save(&calibration_chart::CalibrationChart { rows: &rows }, &stem, (900, 700))?;
    println!("wrote docs/uncertainty.md and {}.{{svg,png}}", stem.display());
    Ok(())
}

/// What `cargo xtask fit` runs.
#[derive(Debug, Clone, PartialEq)]
pub enum Options {
    /// The measurement-fit fixture (fixtures/fit: a truth, one degraded scan).
    Fixture,
    /// Fits of degraded scans against the truth, imposing and no correction (docs/fit.md).
    Study { quick: bool },
    /// Scans of gravity-driven truths fitted with gravity known, off and estimated.
    Gravity { quick: bool },
    /// The gravity-fit fixture (fixtures/fit-gravity).
    GravityFixture,
    /// The calibration of the uncertainty's σ (docs/uncertainty.md).
    Uncertainty { quick: bool },
    /// One scan case written into target/fit-try, for exploring.
    Try { sigma: f64, coverage: f64, outliers: f64, misalignment: f64, free: bool },
    /// `n` landmarks of noise `sigma` fitted into target/fit-try, for exploring.
    Landmarks { n: usize, sigma: f64, seed: u64 },
}

/// `cargo xtask fit …`.
pub fn main(o: &Options) -> Result<(), String> {
    match *o {
        Options::Fixture => fixture(),
        Options::Study { quick } => run_study(quick),
        Options::Gravity { quick } => run_gravity(quick),
        Options::GravityFixture => gravity::fixture(),
        Options::Uncertainty { quick } => run_uncertainty(quick),
        Options::Try { sigma, coverage, outliers, misalignment, free } => {
            let case = Case { sigma, coverage, outliers, misalignment, seed: 47, free };
            let dir = root().join("target/fit-try");
            let t = truth(&dir, &regions().display().to_string())?;
            let text = write_scan(&t, &case, &dir, &regions().display().to_string())?;
            crate::util::write(&dir.join("scene.toml"), &text)?;
            println!("wrote {}", dir.join("scene.toml").display());
            Ok(())
        }
        Options::Landmarks { n, sigma, seed } => {
            let dir = root().join("target/fit-try");
            let t = truth(&dir, &regions().display().to_string())?;
            print!("{}", landmarks::table(&[landmarks::case(&t, n, sigma, seed, &dir)]));
            Ok(())
        }
    }
}
