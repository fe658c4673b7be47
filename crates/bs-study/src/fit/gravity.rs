//! `cargo xtask fit gravity`: gravity-driven truths and the fits of their scans.
//!
//! A truth is the mni152-regions brain (parenchyma, ventricles, tumour; their own
//! materials) under gravity `angle` degrees off the window's axis (−z, tilted towards +x),
//! the cerebrospinal fluid drained above a level `depth` mm below the window's centre along
//! gravity, its weight scaled by `1 + weight`; nothing prescribed. The fits see a
//! homogeneous model (every region the parenchyma's material: what a team without a
//! segmentation of the ventricles would model) and a scan as the sensor model gives it
//! (σ 1 mm, half the window, 5 % outliers, 2 mm misalignment with bone points), and, where
//! a row says so, a scene whose level is 10 mm above the truth's and whose direction is 4°
//! off it. The landmark rows take [`LANDMARKS`] pairs 5–25 mm under the craniotomy at σ
//! 1 mm (the push study's draws): fitted through the craniotomy and imposed by the spline
//! under the scene's (off) gravity, fitted through the craniotomy with the level and direction
//! estimated jointly with the boundary, alone as evidence for the estimate (nothing
//! prescribed), and beside the scan as evidence for the estimate.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use bs_mesh::{Point3, Vector3};
use bs_scene::Prepared;

use super::study::{DeepError, cell};
use super::truth::{self, Case, Truth};

/// How far the scene's level and direction are from the truth's in the rows that do not
/// know them (mm, degrees).
pub const LEVEL_OFF: f64 = 10.0;
pub const DIRECTION_OFF: f64 = 4.0;
/// Prior standard deviations of the estimated rows: level (mm), direction (°), weight.
pub const PRIOR: (f64, f64, f64) = (15.0, 5.0, 0.3);

/// Landmark pairs of the landmark rows, their noise (mm) and their draw's seed.
pub const LANDMARKS: usize = 15;
const LANDMARK_SIGMA: f64 = 1.0;
const LANDMARK_SEED: u64 = 1000;

/// A gravity-driven truth's load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Load {
    /// Degrees off the window's axis (−z), towards +x.
    pub angle: f64,
    /// The fluid's level below the window's centre along gravity (mm).
    pub depth: f64,
    /// The weight's relative change.
    pub weight: f64,
}

impl Load {
    fn down(&self) -> Vector3<f64> {
        let (s, c) = self.angle.to_radians().sin_cos();
        Vector3::new(s, 0.0, -c)
    }

    pub fn label(&self) -> String {
        let w = if self.weight == 0.0 {
            String::new()
        } else {
            format!(", weight {:+.0} %", 100.0 * self.weight)
        };
        format!("{}°, level {} mm{w}", self.angle, self.depth)
    }
}

/// The `[gravity]` table for direction `down`, a level through `level`, weight factor
/// `1 + weight`, and an `estimate` line when given.
fn gravity_table(
    down: Vector3<f64>,
    level: Point3<f64>,
    weight: f64,
    estimate: Option<&str>,
) -> String {
    let mut s = format!(
        "[gravity]\ndirection = [{:?}, {:?}, {:?}]\nacceleration = {:?}\n\
         fluid = {{ density = 1007.0, level = [{:?}, {:?}, {:?}] }}\n",
        down.x,
        down.y,
        down.z,
        9.81 * (1.0 + weight),
        level.x,
        level.y,
        level.z
    );
    if let Some(e) = estimate {
        writeln!(s, "estimate = {e}").unwrap();
    }
    s
}

/// The truth's own `[gravity]`.
fn truth_table(load: &Load, centre: &Point3<f64>) -> String {
    gravity_table(load.down(), centre + load.down() * load.depth, load.weight, None)
}

/// The `[gravity]` a scene believes: the truth's, or with its level 10 mm higher and its
/// direction 4° further towards +x (`off`); the weight always the nominal one.
fn scene_table(load: &Load, centre: &Point3<f64>, off: bool, estimate: Option<&str>) -> String {
    let (angle, depth) = if off {
        (load.angle + DIRECTION_OFF, load.depth - LEVEL_OFF)
    } else {
        (load.angle, load.depth)
    };
    let believed = Load { angle, depth, weight: 0.0 };
    gravity_table(believed.down(), centre + believed.down() * depth, 0.0, estimate)
}

/// The truth of `load`, solved in `dir` (the regions mesh found in `mesh_dir`).
pub fn truth(dir: &Path, mesh_dir: &str, load: &Load) -> Result<Truth, String> {
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let base = Prepared::load(&truth::regions().join("scene.toml")).map_err(|e| e.to_string())?;
    let mesh = base.mesh.clone();
    let skull = base.skull.clone().ok_or("the regions scene has a skull")?;
    let nodes = mesh.node_set("CRANIOTOMY").ok_or("CRANIOTOMY")?.to_vec();
    let centre = *nodes.iter().map(|&a| &mesh.nodes[a]).max_by(|a, b| a.z.total_cmp(&b.z)).unwrap();
    let head = format!("# The truth: gravity {}.\n", load.label());
    let scene = dir.join("scene-truth.toml");
    let text = truth::scene_text(&(head + &truth_table(load, &centre)), mesh_dir);
    crate::util::write(&scene, &text)?;
    let u = truth::solve(&scene)?.u;
    let member: Vec<bool> = (0..mesh.nodes.len()).map(|a| nodes.contains(&a)).collect();
    let faces = truth::patch(&mesh, &member);
    let deep = (0..mesh.nodes.len())
        .filter(|&a| nodes.iter().all(|&c| (mesh.nodes[a] - mesh.nodes[c]).norm() > 15.0))
        .collect();
    Ok(Truth { mesh, skull, nodes, faces, centre, u, deep })
}

/// `text` with every region given the parenchyma's material.
fn homogeneous(text: &str) -> String {
    let brain = text.split("elset = \"BRAIN\"\n").nth(1).and_then(|r| r.lines().next());
    let Some(brain) = brain else { return text.to_string() };
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with("material = ") {
            out += brain;
        } else {
            out += line;
        }
        out.push('\n');
    }
    out
}

/// One fit of the study.
#[derive(Debug, Clone)]
pub struct Row {
    pub truth: Load,
    pub name: &'static str,
    pub error: DeepError,
    pub seconds: f64,
    pub newton: usize,
    /// The estimates' summary (estimated rows).
    pub estimates: String,
}

/// The scene of the estimated row for the scan of `case`: the homogeneous model whose
/// level and direction are off, both estimated with the scan (the uncertainty study's
/// gravity fits).
pub(super) fn estimated_scene(
    t: &Truth,
    load: &Load,
    case: &Case,
    dir: &Path,
    mesh_dir: &str,
) -> Result<String, String> {
    let scan = homogeneous(&truth::write_scan(t, case, dir, mesh_dir)?);
    let (l, d, _) = PRIOR;
    let estimate = format!("{{ level = {l:?}, direction = {d:?} }}");
    let g = scene_table(load, &t.centre, true, Some(&estimate));
    Ok(scan.replace("[contact]", &format!("{g}\n[contact]")))
}

/// The rows' scenes: what each knows.
fn scenes(
    t: &Truth,
    load: &Load,
    dir: &Path,
    mesh_dir: &str,
) -> Result<Vec<(&'static str, String)>, String> {
    let case = Case::target();
    let scan = homogeneous(&truth::write_scan(t, &case, dir, mesh_dir)?);
    let model = homogeneous(&truth::scene_text("", mesh_dir));
    let with = |text: &str, g: String| text.replace("[contact]", &format!("{g}\n[contact]"));
    let c = &t.centre;
    let (l, d, w) = PRIOR;
    let estimate = format!("{{ level = {l:?}, direction = {d:?} }}");
    let estimate_w = format!("{{ level = {l:?}, direction = {d:?}, weight = {w:?} }}");
    let resisted =
        |text: String| text.replace("sigma = 1\n", "sigma = 1\nsliding = \"resisted\"\n");
    let pairs =
        super::landmarks::pairs(t, LANDMARKS, LANDMARK_SIGMA, LANDMARK_SEED + LANDMARKS as u64);
    super::landmarks::write_pairs(&dir.join("landmarks.csv"), &pairs)?;
    let fitted = format!(
        "[[measurement]]\nlandmarks = \"landmarks.csv\"\nnset = \"CRANIOTOMY\"\n\
         sigma = {LANDMARK_SIGMA:?}\n"
    );
    let beside =
        format!("[[measurement]]\nlandmarks = \"landmarks.csv\"\nsigma = {LANDMARK_SIGMA:?}\n");
    let spline = "[[boundary]]\nnset = \"CRANIOTOMY\"\nlandmarks = \"landmarks.csv\"\n\
                  max_extrapolation = 20.0\n";
    let off = scene_table(load, c, true, None);
    Ok(vec![
        ("prior at the true level", with(&model, scene_table(load, c, false, None))),
        ("prior, level and direction off", with(&model, scene_table(load, c, true, None))),
        ("scan alone", scan.clone()),
        (
            "scan, gravity off, sliding resisted",
            resisted(with(&scan, scene_table(load, c, true, None))),
        ),
        ("scan, gravity off, sliding free", with(&scan, scene_table(load, c, true, None))),
        (
            "scan, level and direction estimated",
            with(&scan, scene_table(load, c, true, Some(&estimate))),
        ),
        (
            "scan, level, direction and weight estimated",
            with(&scan, scene_table(load, c, true, Some(&estimate_w))),
        ),
        ("landmarks, gravity off", with(&model, format!("{fitted}\n{off}"))),
        (
            "landmarks through the craniotomy, level and direction estimated",
            with(&model, format!("{fitted}\n{}", scene_table(load, c, true, Some(&estimate)))),
        ),
        (
            "landmarks as evidence only, level and direction estimated",
            with(&model, format!("{beside}\n{}", scene_table(load, c, true, Some(&estimate)))),
        ),
        ("spline of the landmarks, gravity off", with(&model, format!("{spline}\n{off}"))),
        (
            "scan and landmarks, level and direction estimated",
            with(&scan, format!("{beside}\n{}", scene_table(load, c, true, Some(&estimate)))),
        ),
    ])
}

/// The rows of one truth.
pub fn rows(load: &Load, dir: &Path, mesh_dir: &str) -> Result<Vec<Row>, String> {
    let t = truth(dir, mesh_dir, load)?;
    let mut out = vec![Row {
        truth: *load,
        name: "no correction",
        error: Ok(truth::deep_error(&t, &vec![Vector3::zeros(); t.u.len()])),
        seconds: 0.0,
        newton: 0,
        estimates: String::new(),
    }];
    for (k, (name, text)) in scenes(&t, load, dir, mesh_dir)?.into_iter().enumerate() {
        let scene = dir.join(format!("scene-{k}.toml"));
        crate::util::write(&scene, &text)?;
        let started = Instant::now();
        let s = truth::solve(&scene);
        let seconds = started.elapsed().as_secs_f64();
        let estimates = match &s {
            Ok(s) => {
                s.gravity.as_ref().filter(|g| !g.estimates.is_empty()).map_or(String::new(), |g| {
                    let mut e = format!("{}; {} solves", g.summary("mm"), g.solves);
                    if !g.data_used {
                        e += "; data not used";
                    }
                    if let Some(n) = &g.note {
                        e += &format!(" ({n})");
                    }
                    e
                })
            }
            Err(_) => String::new(),
        };
        let row = Row {
            truth: *load,
            name,
            newton: s.as_ref().map_or(0, |s| s.iterations),
            error: s.map(|s| truth::deep_error(&t, &s.u)),
            seconds,
            estimates,
        };
        eprintln!(
            "{}: {name}: {} ({seconds:.1} s) {}",
            load.label(),
            cell(&row.error),
            row.estimates
        );
        out.push(row);
    }
    Ok(out)
}

/// The truths of the study (`quick`: one).
pub fn loads(quick: bool) -> Vec<Load> {
    let l = |angle, depth, weight| Load { angle, depth, weight };
    if quick {
        return vec![l(30.0, 25.0, 0.0)];
    }
    vec![
        l(0.0, 25.0, 0.0),
        l(30.0, 25.0, 0.0),
        l(60.0, 25.0, 0.0),
        l(30.0, 15.0, 0.0),
        l(30.0, 40.0, 0.0),
        l(30.0, 25.0, 0.3),
        l(30.0, 25.0, -0.3),
    ]
}

/// The table of docs/fit.md.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| truth: gravity off the window's axis, level below its centre | fit | deep mean / p95 (mm) | solve (s) | Newton iterations | estimated (offsets from the scene's) |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        writeln!(
            s,
            "| {} | {} | {} | {:.2} | {} | {} |",
            r.truth.label(),
            r.name,
            cell(&r.error),
            r.seconds,
            r.newton,
            crate::util::escape_cell(&r.estimates)
        )
        .unwrap();
    }
    s
}

/// `cargo xtask fit gravity-fixture`: `fixtures/fit-gravity/`, the 30° truth with its
/// level 25 mm below the window's centre: the truth (scene-truth.toml, truth.csv), the
/// scan of the target case (scan.csv, bone.csv), the fit estimating level and direction
/// from a scene 10 mm and 4° off (scene.toml) and that scene's forward solve without the
/// scan (scene-forward.toml).
pub fn fixture() -> Result<(), String> {
    let dir = crate::util::root().join("fixtures/fit-gravity");
    let mesh_dir = "../mni152-regions";
    let load = Load { angle: 30.0, depth: 25.0, weight: 0.0 };
    let t = truth(&dir, mesh_dir, &load)?;
    let mut csv = String::from("node_id,ux,uy,uz\n");
    for (id, d) in t.mesh.node_ids.iter().zip(&t.u) {
        writeln!(csv, "{id},{:?},{:?},{:?}", d.x, d.y, d.z).unwrap();
    }
    crate::util::write(&dir.join("truth.csv"), &csv)?;
    let scenes = scenes(&t, &load, &dir, mesh_dir)?;
    let pick = |name: &str| scenes.iter().find(|(n, _)| *n == name).map(|(_, s)| s.clone());
    let fit = pick("scan, level and direction estimated").ok_or("the estimated row")?;
    let forward = pick("prior, level and direction off").ok_or("the forward row")?;
    crate::util::write(&dir.join("scene.toml"), &fit)?;
    crate::util::write(&dir.join("scene-forward.toml"), &forward)?;
    let s = truth::solve(&dir.join("scene.toml"))?;
    let (mean, p95, _) = truth::deep_error(&t, &s.u);
    println!(
        "fixtures/fit-gravity: fit deep error mean {mean:.3} mm, p95 {p95:.3} ({:.1} s); {}",
        s.seconds,
        s.gravity.map(|g| g.summary("mm")).unwrap_or_default()
    );
    Ok(())
}
