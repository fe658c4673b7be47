//! `cargo xtask fit study`: fits of degraded scans of the truth, against the coverage
//! oracle, against imposing the scan node by node, and against no correction; one row per
//! case, the table of docs/fit.md and its chart.

use std::fmt::Write as _;
use std::path::Path;

use bs_mesh::{TriSurface, Vector3};

use super::truth::{self, Case, Solve, Truth};

/// Deep-node error (mean, p95, max in mm), or why the run failed.
pub type DeepError = Result<(f64, f64, f64), String>;

/// A coverage oracle: the coverage fraction and its deep error.
pub type Oracle = (f64, DeepError);

/// One row of the study.
#[derive(Debug, Clone)]
pub struct Row {
    pub group: &'static str,
    pub case: Case,
    /// The fit's deep error (mean, p95, max), or why it failed.
    pub fit: DeepError,
    pub solve: Option<(f64, usize, f64)>,
    /// Inliers of the points read; how far the corrected scan is from the truth at the
    /// window's centre (the misalignment the rigid correction left, mm).
    pub inliers: Option<(usize, usize)>,
    pub rigid: Option<f64>,
}

/// The coverage oracle: the exact displacement vectors of the covered craniotomy nodes
/// imposed, the rest free. Deep error (mean, p95, max).
pub fn oracle(t: &Truth, coverage: f64, dir: &Path) -> Result<(f64, f64, f64), String> {
    let case =
        Case { sigma: 0.0, coverage, outliers: 0.0, misalignment: 0.0, seed: 0, free: false };
    let cut = case.coverage();
    let centre = truth::window_centre(t);
    let deformed = truth::deformed(t);
    let mut csv = String::from("node_id,ux,uy,uz\n");
    for &a in &t.nodes {
        if cut.sees(&(deformed[a] - centre)) {
            let d = t.u[a];
            writeln!(csv, "{},{:?},{:?},{:?}", t.mesh.node_ids[a], d.x, d.y, d.z).unwrap();
        }
    }
    let name = format!("oracle-{}", (coverage * 100.0) as u32);
    crate::util::write(&dir.join(format!("{name}.csv")), &csv)?;
    let boundary =
        format!("[[boundary]]\nnset = \"CRANIOTOMY\"\ndisplacement_file = \"{name}.csv\"\n");
    let scene = dir.join(format!("{name}.toml"));
    let mesh_dir = truth::regions().display().to_string();
    crate::util::write(&scene, &truth::scene_text(&boundary, &mesh_dir))?;
    Ok(truth::deep_error(t, &truth::solve(&scene)?.u))
}

/// Today's way: the scanned surface imposed node by node (`[[boundary]] surface`), the
/// truth's deformed patch with noise `sigma` on its vertices as an STL.
pub fn imposed(t: &Truth, sigma: f64, dir: &Path) -> Result<(f64, f64, f64), String> {
    let deformed = truth::deformed(t);
    let mut rng = bs_mesh::rng::SplitMix64::new(5);
    let mut index = std::collections::HashMap::new();
    let mut vertices = Vec::new();
    let triangles = t
        .faces
        .iter()
        .map(|f| {
            f.map(|a| {
                *index.entry(a).or_insert_with(|| {
                    let noise = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
                    vertices.push(deformed[a] + noise);
                    vertices.len() - 1
                })
            })
        })
        .collect();
    let stl = dir.join(format!("imposed-{}.stl", (sigma * 10.0) as u32));
    bs_mesh::io::write_surface(&stl, &TriSurface { vertices, triangles })
        .map_err(|e| e.to_string())?;
    let boundary = format!(
        "[[boundary]]\nnset = \"CRANIOTOMY\"\nsurface = {:?}\n",
        stl.file_name().unwrap_or_default()
    );
    let scene = dir.join(format!("imposed-{}.toml", (sigma * 10.0) as u32));
    crate::util::write(
        &scene,
        &truth::scene_text(&boundary, &truth::regions().display().to_string()),
    )?;
    Ok(truth::deep_error(t, &truth::solve(&scene)?.u))
}

/// Fits `case` in `dir`.
pub fn fit(t: &Truth, group: &'static str, case: Case, dir: &Path) -> Row {
    let run = || -> Result<Solve, String> {
        let text = truth::write_scan(t, &case, dir, &truth::regions().display().to_string())?;
        let scene = dir.join("scene.toml");
        crate::util::write(&scene, &text)?;
        truth::solve(&scene)
    };
    match run() {
        Ok(s) => Row {
            group,
            case,
            fit: Ok(truth::deep_error(t, &s.u)),
            solve: Some((s.seconds, s.iterations, s.min_jacobian)),
            inliers: s.measurement.as_ref().map(|m| (m.inliers, m.points)),
            rigid: s.measurement.as_ref().and_then(|m| m.rigid.as_ref()).map(|r| {
                let axis = Vector3::from(r.axis);
                let rotation = nalgebra::Rotation3::new(axis * r.angle_degrees.to_radians());
                let fix = bs_fit::Rigid { rotation, translation: Vector3::from(r.translation) };
                let c = t.centre;
                (fix.apply(&case.misalignment(&c).apply(&c)) - c).norm()
            }),
        },
        Err(e) => Row { group, case, fit: Err(e), solve: None, inliers: None, rigid: None },
    }
}

/// The cases: noise × coverage (clean otherwise), outliers × misalignment at σ = 1 mm and
/// half coverage, and the target cases.
pub fn cases(quick: bool) -> Vec<(&'static str, Case)> {
    let c = |sigma, coverage, outliers, misalignment| Case {
        sigma,
        coverage,
        outliers,
        misalignment,
        seed: 47,
        free: false,
    };
    let mut v = Vec::new();
    let sigmas: &[f64] = if quick { &[0.0, 1.0] } else { &[0.0, 0.5, 1.0, 2.0] };
    for &coverage in &[1.0, 0.5, 0.25] {
        for &s in sigmas {
            v.push(("noise × coverage", c(s, coverage, 0.0, 0.0)));
        }
    }
    if !quick {
        for &o in &[0.05, 0.10] {
            v.push(("outliers", c(1.0, 0.5, o, 0.0)));
        }
        v.push(("misalignment", c(1.0, 0.5, 0.0, 2.0)));
    }
    v.push(("target", c(1.0, 0.5, 0.05, 2.0)));
    v.push(("target", c(2.0, 0.25, 0.10, 0.0)));
    v
}

/// A deep-error cell.
pub fn cell(e: &DeepError) -> String {
    match e {
        Ok((mean, p95, _)) => format!("{mean:.2} / {p95:.2}"),
        Err(m) if m.contains("invert") => "fails: an element inverts".into(),
        Err(m) => {
            // The message without the scene's path and the study folder (machine-specific).
            let m = m.split_once(".toml: ").map_or(m.as_str(), |(_, rest)| rest);
            let folder = format!("{}/", crate::util::root().join("target/fit-study").display());
            let short: String = m.replace(&folder, "").chars().take(120).collect();
            format!("fails: {}…", crate::util::escape_cell(&short))
        }
    }
}

/// The table of the rows (Markdown).
pub fn table(rows: &[Row], oracles: &[Oracle], none: (f64, f64, f64)) -> String {
    let mut s = String::from(
        "| group | σ (mm) | coverage | outliers | misalignment | fit: deep mean / p95 (mm) | \
         coverage oracle | solve (s) | iterations | min J | inliers | misalignment left (mm) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let c = &r.case;
        let oracle = oracles
            .iter()
            .find(|(cov, _)| *cov == c.coverage)
            .map_or(String::new(), |(_, e)| cell(e));
        let (secs, its, j) =
            r.solve.map_or((String::new(), String::new(), String::new()), |(s, i, j)| {
                (format!("{s:.2}"), i.to_string(), format!("{j:.2}"))
            });
        writeln!(
            s,
            "| {} | {} | {} % | {} % | {} mm | {} | {oracle} | {secs} | {its} | {j} | {} | {} |",
            r.group,
            c.sigma,
            c.coverage * 100.0,
            c.outliers * 100.0,
            c.misalignment,
            cell(&r.fit),
            r.inliers.map_or(String::new(), |(i, n)| format!("{i} of {n}")),
            r.rigid.map_or(String::new(), |t| format!("{t:.2}")),
        )
        .unwrap();
    }
    writeln!(
        s,
        "\nNo correction at all (the pre-operative brain): deep mean {:.2} mm, p95 {:.2} mm.",
        none.0, none.1
    )
    .unwrap();
    s
}

/// One row of the sliding comparison: the truth's tilt, the case, and the deep error with
/// the sliding prior (the default) and without it.
pub struct SlidingRow {
    pub tilt: f64,
    pub case: Case,
    pub resisted: DeepError,
    pub free: DeepError,
}

/// The sliding prior against free sliding, on the truth and on a truth whose sag is tilted
/// `TILT` degrees off the window's axis (where the prior's direction is wrong).
pub fn sliding(t: &Truth, dir: &Path, quick: bool) -> Result<Vec<SlidingRow>, String> {
    const TILT: f64 = 30.0;
    let tilted_dir = dir.join("tilted");
    let tilted = truth::truth_tilted(&tilted_dir, &truth::regions().display().to_string(), TILT)?;
    let cases: Vec<Case> =
        cases(quick).into_iter().filter(|(g, _)| *g == "target").map(|c| c.1).collect();
    let exact =
        Case { sigma: 0.0, coverage: 1.0, outliers: 0.0, misalignment: 0.0, seed: 47, free: false };
    let mut rows = Vec::new();
    for (tilt, truth, d) in [(0.0, t, dir), (TILT, &tilted, tilted_dir.as_path())] {
        for &case in std::iter::once(&exact).chain(&cases) {
            let resisted = fit(truth, "sliding", case, d).fit;
            let free = fit(truth, "sliding", Case { free: true, ..case }, d).fit;
            eprintln!("sliding, tilt {tilt}: {case:?}: {} / free {}", cell(&resisted), cell(&free));
            rows.push(SlidingRow { tilt, case, resisted, free });
        }
    }
    Ok(rows)
}

/// The sliding comparison's table (Markdown).
pub fn sliding_table(rows: &[SlidingRow]) -> String {
    let mut s = String::from(
        "| truth's sag | σ (mm) | coverage | outliers | misalignment | sliding resisted (default): deep mean / p95 (mm) | sliding free |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let c = &r.case;
        let sag =
            if r.tilt == 0.0 { "along −z".to_string() } else { format!("{}° off −z", r.tilt) };
        writeln!(
            s,
            "| {sag} | {} | {} % | {} % | {} mm | {} | {} |",
            c.sigma,
            c.coverage * 100.0,
            c.outliers * 100.0,
            c.misalignment,
            cell(&r.resisted),
            cell(&r.free)
        )
        .unwrap();
    }
    s
}
