//! `cargo xtask chart`: speed against accuracy. Every configuration of a case (mesh density,
//! element technology, DR tolerance, contact handler; DR against Newton without contact) is
//! solved through the code path of `brainshift run` ([`crate::study`]), timed, and compared
//! with the finest converged solution of the case: the finest mesh, T4ANP, DR tolerance
//! 1e-5 mm. Results on other meshes are compared at their own nodes, with the reference
//! carried over by [`bs_mesh::TetLocator`]. CalculiX's stored solutions are placed on the
//! same axes (their stored run time, measured on this kind of machine by `cargo xtask
//! reference`).
//!
//! Writes `docs/charts/speed-accuracy-<case>.{svg,png,csv}`, `docs/charts/dr-vs-newton.*`,
//! the findings table into `docs/speed-accuracy.md` (between markers) and the findings that
//! `brainshift check` prints as advice into `crates/bs-scene/data/speed-accuracy.json`.

use std::path::{Path, PathBuf};

use crate::speed_accuracy::{
    ChartPoint, TARGETS, findings_of, from_csv, markdown, pareto_front, to_csv,
};
use crate::study::{ContactChoice, Variant, difference};
use bs_mesh::quality::mean_edge_length;
use bs_mesh::{TetLocator, Vector3, transfer};
use bs_scene::prepare::Prepared;
use bs_scene::scene::{Algorithm, ElementChoice, SolverKind};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::plot::{self, Figure, PALETTE, err};

/// Colours of the sweep lines: the Okabe–Ito palette without black (CalculiX's) and a few
/// darker shades, so up to ten series stay apart.
const SERIES_COLORS: [RGBColor; 10] = [
    PALETTE[0],
    PALETTE[1],
    PALETTE[2],
    PALETTE[3],
    PALETTE[4],
    PALETTE[5],
    RGBColor(0, 70, 110),
    RGBColor(140, 60, 0),
    RGBColor(0, 100, 70),
    RGBColor(150, 150, 0),
];
use crate::calculix::read_reference;
use crate::util::{replace_block, root, write};

/// Tolerance of the reference solution of each case (mm); Newton–Krylov, whose error
/// estimate is the last correction of a superlinear iteration.
pub const REFERENCE_TOLERANCE: f64 = 1e-6;
/// The solvers of the sweeps: the default and the paper's.
const SOLVERS: [SolverKind; 2] = [SolverKind::NewtonKrylov, SolverKind::Dr];

/// Short name of a solver in series names.
fn short(s: SolverKind) -> &'static str {
    match s {
        SolverKind::NewtonKrylov => "NK",
        SolverKind::Dr => "DR",
        SolverKind::Newton => "Newton",
    }
}
/// Tolerances of the sweep (mm).
pub const TOLERANCES: [f64; 4] = [1e-1, 1e-2, 1e-3, 1e-4];

/// A case: its mesh levels from coarse to fine (scene files), and which level CalculiX's
/// stored references were computed on.
#[derive(Debug, Clone)]
pub struct Case {
    name: &'static str,
    levels: Vec<(&'static str, &'static str)>,
    ccx_level: &'static str,
    /// Brute-force contact is run only where it takes minutes, not hours.
    brute_force: bool,
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "ellipsoid",
            levels: vec![
                ("coarse", "fixtures/ellipsoid/scene.toml"),
                ("medium", "fixtures/ellipsoid/scene-medium.toml"),
                ("fine", "fixtures/ellipsoid/scene-fine.toml"),
            ],
            ccx_level: "coarse",
            brute_force: true,
        },
        Case {
            name: "mni152",
            levels: vec![
                ("coarse", "fixtures/mni152/scene-coarse.toml"),
                ("default", "fixtures/mni152/scene.toml"),
                ("fine", "fixtures/mni152/scene-fine.toml"),
            ],
            ccx_level: "default",
            brute_force: false,
        },
    ]
}

/// A level of a case with the reference carried onto its nodes.
struct Level {
    label: &'static str,
    p: Prepared,
    reference: Vec<Vector3<f64>>,
    mean_edge: f64,
    /// CalculiX K = 10 on this level, where stored.
    ccx: Option<Vec<Vector3<f64>>>,
}

/// Bounding-box diagonal of a scene's mesh (mesh units: mm for every case here).
fn diagonal(p: &Prepared) -> f64 {
    p.mesh.bounding_box().map_or(f64::NAN, |(a, b)| (b - a).norm())
}

/// Solves `v` on `level` and measures it against the level's reference field.
fn measure(case: &str, series: &str, level: &Level, v: &Variant) -> Result<ChartPoint, String> {
    let q = v.apply(&level.p).map_err(|e| e.to_string())?;
    let o = v.solve(&level.p).map_err(|e| format!("{case} {} {v:?}: {e}", level.label))?;
    let (mean, max) = difference(&o.displacements, &level.reference, None);
    let point = ChartPoint {
        case: case.into(),
        series: series.into(),
        level: level.label.into(),
        element: ElementChoice::name(q.element).into(),
        solver: q.scene.solver.kind.name().into(),
        handler: q.scene.contact.as_ref().map_or("none", |c| c.algorithm.name()).into(),
        tolerance: q.scene.solver.tolerance,
        nodes: level.p.mesh.nodes.len(),
        mean_edge: level.mean_edge,
        diagonal: diagonal(&level.p),
        seconds: o.setup_seconds + o.solve_seconds,
        steps: o.steps,
        mean_error: mean,
        max_error: max,
        mean_error_ccx: level.ccx.as_ref().map(|u| difference(&o.displacements, u, None).0),
        is_reference: false,
    };
    println!(
        "{:<10} {:<44} {:>8.2} s {:>7} steps  mean {:.2e} max {:.2e} mm",
        case,
        point.label(),
        point.seconds,
        point.steps,
        mean,
        max
    );
    Ok(point)
}

/// Loads the levels and solves `reference` on the finest, carrying its field onto the
/// nodes of every level. Returns the levels and the reference's own point.
fn levels_with_reference(
    case: &Case,
    reference: &Variant,
) -> Result<(Vec<Level>, ChartPoint), String> {
    let mut preps = Vec::new();
    for (label, path) in &case.levels {
        let p = Prepared::load(&root().join(path)).map_err(|e| format!("{path}: {e}"))?;
        preps.push((*label, p));
    }
    let (finest_label, finest) = preps.last().ok_or("a case needs at least one level")?;
    let o = reference.solve(finest).map_err(|e| format!("{} reference: {e}", case.name))?;
    let locator = TetLocator::new(&finest.mesh).map_err(|e| e.to_string())?;
    let levels: Vec<Level> = preps
        .iter()
        .map(|(label, p)| Level {
            label,
            reference: transfer(&locator, &o.displacements, &p.mesh.nodes),
            mean_edge: mean_edge_length(&p.mesh),
            p: p.clone(),
            ccx: None,
        })
        .collect();
    let q = reference.apply(finest).map_err(|e| e.to_string())?;
    let point = ChartPoint {
        case: case.name.into(),
        series: "reference".into(),
        level: (*finest_label).into(),
        element: ElementChoice::name(q.element).into(),
        solver: q.scene.solver.kind.name().into(),
        handler: q.scene.contact.as_ref().map_or("none", |c| c.algorithm.name()).into(),
        tolerance: q.scene.solver.tolerance,
        nodes: finest.mesh.nodes.len(),
        mean_edge: mean_edge_length(&finest.mesh),
        diagonal: diagonal(finest),
        seconds: o.setup_seconds + o.solve_seconds,
        steps: o.steps,
        mean_error: 0.0,
        max_error: 0.0,
        mean_error_ccx: None,
        is_reference: true,
    };
    println!(
        "{:<10} reference {} ({:.1} s, {} steps)",
        case.name,
        point.label(),
        point.seconds,
        o.steps
    );
    Ok((levels, point))
}

/// The speed–accuracy sweep of one case with contact.
fn contact_sweep(case: &Case) -> Result<Vec<ChartPoint>, String> {
    let reference = Variant {
        element: Some(ElementChoice::T4anp),
        tolerance: Some(REFERENCE_TOLERANCE),
        solver: Some(SolverKind::NewtonKrylov),
        ..Variant::default()
    };
    let (mut levels, ref_point) = levels_with_reference(case, &reference)?;
    let mut points = vec![ref_point];
    calculix_points(case, &mut levels, &mut points)?;
    for level in &levels {
        for solver in SOLVERS {
            for element in [ElementChoice::T4, ElementChoice::T4anp] {
                let series =
                    format!("{} {} {}", ElementChoice::name(element), level.label, short(solver));
                for tol in TOLERANCES {
                    let v = Variant {
                        element: Some(element),
                        tolerance: Some(tol),
                        solver: Some(solver),
                        ..Variant::default()
                    };
                    points.push(measure(case.name, &series, level, &v)?);
                }
            }
        }
    }
    // Contact handlers in DR's per-step enforcement on the coarsest level (T4ANP, 1e-3 mm;
    // brute force costs minutes even there): the scene's own handler is already in the
    // sweep.
    let middle = &levels[0];
    let own = middle.p.scene.contact.as_ref().map(|c| c.algorithm);
    for a in [Algorithm::Paper, Algorithm::Coherent, Algorithm::Parry, Algorithm::BruteForce] {
        if Some(a) == own || (a == Algorithm::BruteForce && !case.brute_force) {
            continue;
        }
        let v = Variant {
            element: Some(ElementChoice::T4anp),
            tolerance: Some(1e-3),
            contact: Some(ContactChoice::Handler(a)),
            solver: Some(SolverKind::Dr),
            ..Variant::default()
        };
        points.push(measure(case.name, "handlers", middle, &v)?);
    }
    Ok(points)
}

/// CalculiX's stored solutions as points, at their stored wall time; the K = 10 field is
/// kept on its level so every point solved there is also measured against it.
fn calculix_points(
    case: &Case,
    levels: &mut [Level],
    points: &mut Vec<ChartPoint>,
) -> Result<(), String> {
    let Some(level) = levels.iter_mut().find(|l| l.label == case.ccx_level) else {
        return Ok(());
    };
    let dir = root().join("fixtures").join(case.name).join("reference");
    for (tag, k) in [("ccx-k10", "K=10"), ("ccx-k1", "K=1")] {
        let Some(r) = read_reference(&dir, tag)? else { continue };
        if r.meta["converged"] != serde_json::Value::Bool(true) {
            continue;
        }
        let u = crate::calculix::field(&level.p, &r, tag)?;
        let (mean, max) = difference(&u, &level.reference, None);
        points.push(ChartPoint {
            case: case.name.into(),
            series: "CalculiX".into(),
            level: level.label.into(),
            element: "c3d4".into(),
            solver: "calculix".into(),
            handler: format!("penalty {k}"),
            tolerance: f64::NAN,
            nodes: level.p.mesh.nodes.len(),
            mean_edge: level.mean_edge,
            diagonal: diagonal(&level.p),
            seconds: r.meta["wall_seconds"].as_f64().unwrap_or(f64::NAN),
            steps: 0,
            mean_error: mean,
            max_error: max,
            mean_error_ccx: None,
            is_reference: false,
        });
        if tag == "ccx-k10" {
            level.ccx = Some(u);
        }
    }
    Ok(())
}

/// DR and Newton–Krylov against Newton without contact on the ellipsoid levels (T4: Newton
/// has no T4ANP), against the finest Newton solution.
fn newton_sweep(case: &Case) -> Result<Vec<ChartPoint>, String> {
    let base = Variant {
        element: Some(ElementChoice::T4),
        contact: Some(ContactChoice::Off),
        ..Variant::default()
    };
    let reference =
        Variant { solver: Some(SolverKind::Newton), tolerance: Some(1e-8), ..base.clone() };
    let (levels, ref_point) = levels_with_reference(case, &reference)?;
    let mut points = vec![ref_point];
    for level in &levels {
        for solver in SOLVERS {
            for tol in [1e-2, 1e-3, 1e-4] {
                let v = Variant { tolerance: Some(tol), solver: Some(solver), ..base.clone() };
                let series = format!("{} t4 {}", short(solver), level.label);
                points.push(measure(case.name, &series, level, &v)?);
            }
        }
        if level.label != levels.last().map_or("", |l| l.label) {
            points.push(measure(case.name, "Newton t4", level, &reference)?);
        }
    }
    Ok(points)
}

/// The chart of one case: log-log, one line per tolerance sweep, handler and CalculiX
/// points labelled, the Pareto front dashed, the targets dotted.
struct SpeedAccuracy<'a> {
    title: String,
    points: &'a [ChartPoint],
}

impl Figure for SpeedAccuracy<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let shown: Vec<&ChartPoint> = self
            .points
            .iter()
            .filter(|p| !p.is_reference && p.mean_error > 0.0 && p.seconds > 0.0)
            .collect();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, 0.0f64, f64::MAX, 0.0f64);
        for p in &shown {
            x0 = x0.min(p.seconds);
            x1 = x1.max(p.seconds);
            y0 = y0.min(p.mean_error);
            y1 = y1.max(p.mean_error);
        }
        if shown.is_empty() {
            return Err("nothing to draw".into());
        }
        let (x0, x1) = (x0 / 1.5, x1 * 1.5);
        let (y0, y1) = (y0.min(TARGETS[0]) / 2.0, y1.max(TARGETS[1]) * 2.0);
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("wall time, setup + solve (s), 2 threads")
            .y_desc("mean nodal error vs finest solution (mm)")
            .x_label_formatter(&|x| if *x >= 1.0 { format!("{x:.0}") } else { format!("{x:.1}") })
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .draw()
            .map_err(err)?;
        for t in TARGETS {
            chart
                .draw_series(LineSeries::new(
                    [(x0, t), (x1, t)],
                    ShapeStyle::from(&RGBColor(150, 150, 150)).stroke_width(1),
                ))
                .map_err(err)?
                .label(format!("target {t} mm"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RGBColor(150, 150, 150)));
        }
        let mut series: Vec<&str> = Vec::new();
        for p in &shown {
            if !series.contains(&p.series.as_str()) {
                series.push(&p.series);
            }
        }
        for (k, name) in series.iter().enumerate() {
            let color = match *name {
                "CalculiX" => BLACK,
                "handlers" => RGBColor(120, 60, 160),
                _ => SERIES_COLORS[k % SERIES_COLORS.len()],
            };
            let mut pts: Vec<&&ChartPoint> = shown.iter().filter(|p| p.series == *name).collect();
            pts.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
            let xy: Vec<(f64, f64)> = pts.iter().map(|p| (p.seconds, p.mean_error)).collect();
            let lines = *name != "CalculiX" && *name != "handlers";
            if lines {
                chart.draw_series(LineSeries::new(xy.clone(), &color)).map_err(err)?;
            }
            let solid = *name == "CalculiX";
            let newton_krylov = name.ends_with(" NK") || name.starts_with("NK ");
            chart
                .draw_series(xy.iter().map(|&c| {
                    if solid {
                        Cross::new(c, 6, color.stroke_width(2)).into_dyn()
                    } else if newton_krylov {
                        TriangleMarker::new(c, 5, color.filled()).into_dyn()
                    } else {
                        Circle::new(c, 4, color.filled()).into_dyn()
                    }
                }))
                .map_err(err)?
                .label(*name)
                .legend(move |(x, y)| {
                    if solid {
                        Cross::new((x + 8, y), 5, color.stroke_width(2)).into_dyn()
                    } else if newton_krylov {
                        TriangleMarker::new((x + 8, y), 5, color.filled()).into_dyn()
                    } else {
                        Circle::new((x + 8, y), 4, color.filled()).into_dyn()
                    }
                });
            if !lines {
                chart
                    .draw_series(pts.iter().map(|p| {
                        let text = if p.solver == "calculix" {
                            format!("ccx {}", p.handler.trim_start_matches("penalty "))
                        } else {
                            p.handler.clone()
                        };
                        // CalculiX's two slopes land on one spot: K=1 below, K=10 above.
                        let dy = if p.handler.ends_with("K=1") { 0.8 } else { 1.1 };
                        Text::new(text, (p.seconds * 1.08, p.mean_error * dy), ("sans-serif", 13))
                    }))
                    .map_err(err)?;
            }
        }
        let front: Vec<(f64, f64)> = pareto_front(self.points)
            .into_iter()
            .map(|i| (self.points[i].seconds, self.points[i].mean_error))
            .collect();
        let mut steps = Vec::new();
        for (k, &(x, y)) in front.iter().enumerate() {
            if k > 0 {
                steps.push((x, front[k - 1].1));
            }
            steps.push((x, y));
        }
        chart
            .draw_series(DashedLineSeries::new(
                steps,
                6,
                4,
                ShapeStyle::from(&BLACK).stroke_width(1),
            ))
            .map_err(err)?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        Ok(())
    }
}

fn charts_dir() -> PathBuf {
    root().join("docs/charts")
}

/// Reads points back from a CSV written by [`crate::speed_accuracy::to_csv`]; the mesh
/// diagonal (not stored) is taken from the case's scenes.
pub fn read_csv(path: &Path, case: &Case) -> Result<Vec<ChartPoint>, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: {e} (run `cargo xtask chart` first)", path.display()))?;
    let mut diagonals = std::collections::HashMap::new();
    for (label, scene) in &case.levels {
        let p = Prepared::load(&root().join(scene)).map_err(|e| format!("{scene}: {e}"))?;
        diagonals.insert(label.to_string(), diagonal(&p));
    }
    from_csv(&text, &path.display().to_string(), &|level| {
        diagonals.get(level).copied().unwrap_or(f64::NAN)
    })
}

/// What `cargo xtask chart` draws.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Options {
    /// One case alone (`ellipsoid` or `mni152`), printed; every case writes the docs.
    pub case: Option<String>,
    /// Redraw from the CSV files of the last run instead of solving again.
    pub replot: bool,
}

/// `cargo xtask chart [--case NAME] [--replot]`.
pub fn main(o: &Options) -> Result<(), String> {
    let (only, replot) = (o.case.clone(), o.replot);
    let selected: Vec<Case> =
        cases().into_iter().filter(|c| only.as_deref().is_none_or(|n| n == c.name)).collect();
    if selected.is_empty() {
        return Err(format!("no case named {}", only.unwrap_or_default()));
    }
    // Solves (or, with --replot, re-reads) one sweep and draws it.
    let sweep = |stem: &Path,
                 case: &Case,
                 title: String,
                 solve: &dyn Fn(&Case) -> Result<Vec<ChartPoint>, String>| {
        let points = if replot {
            read_csv(&stem.with_extension("csv"), case)?
        } else {
            let points = solve(case)?;
            write(&stem.with_extension("csv"), &to_csv(&points))?;
            points
        };
        plot::save(&SpeedAccuracy { title, points: &points }, stem, (1100, 750))?;
        Ok::<_, String>(points)
    };
    let mut all = Vec::new();
    let mut findings = String::new();
    for case in &selected {
        let stem = charts_dir().join(format!("speed-accuracy-{}", case.name));
        let title = format!("{}: speed vs accuracy (DR + kinematic contact)", case.name);
        let points = sweep(&stem, case, title, &contact_sweep)?;
        findings.push_str(&markdown(case.name, &points));
        findings.push('\n');
        all.push((case.name.to_string(), points));
    }
    if let Some(ell) = selected.iter().find(|c| c.name == "ellipsoid") {
        let stem = charts_dir().join("dr-vs-newton-ellipsoid");
        let title = "ellipsoid without skull: DR vs Newton (T4)".to_string();
        let points = sweep(&stem, ell, title, &newton_sweep)?;
        findings.push_str(&markdown("ellipsoid without skull (DR vs Newton)", &points));
    }
    if only.is_none() {
        replace_block(&root().join("docs/speed-accuracy.md"), "findings", &findings)?;
        let json = serde_json::to_string_pretty(&findings_of(&all)).map_err(|e| e.to_string())?;
        write(&root().join("crates/bs-scene/data/speed-accuracy.json"), &(json + "\n"))?;
    } else {
        print!("{findings}");
    }
    println!("charts written to {}", charts_dir().display());
    Ok(())
}
