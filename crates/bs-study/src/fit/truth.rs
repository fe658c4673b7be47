//! The truth a fit is measured against, and the scans a sensor would make of it.
//!
//! The truth is the mni152-regions brain (parenchyma, ventricles, tumour; its own materials)
//! whose craniotomy sags in a bell (7 mm deep at the window's top, 15 mm wide), solved once.
//! A sensor model (`bs_fit::synthetic`) scans the truly deformed exposed surface: noise,
//! partial coverage, outliers, misalignment, bone points around the window. The fit sees
//! only the scan; its error is measured at the deep nodes (farther than 15 mm from every
//! craniotomy node), against imposing the exact displacements of the covered nodes (the
//! coverage oracle) and against no correction at all.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use bs_fit::Rigid;
use bs_fit::synthetic::{self, Coverage, ScanParams};
use bs_mesh::{Mesh, Point3, Vector3};
use bs_scene::{Prepared, Run};
use nalgebra::Rotation3;

use crate::util::root;

/// The bell of the truth: depth and width (mm).
const BELL_DEPTH: f64 = 7.0;
const BELL_WIDTH: f64 = 15.0;
/// Deep nodes are farther than this from every craniotomy node (mm).
const DEEP: f64 = 15.0;
/// Scanned points per mm² of the exposed surface (a dense range scanner gives more).
const DENSITY: f64 = 0.5;
/// Bone points per mm² of the skull around the window.
const BONE_DENSITY: f64 = 0.25;

/// The truth and what every case shares.
pub struct Truth {
    pub mesh: Mesh,
    pub skull: bs_mesh::TriSurface,
    /// CRANIOTOMY nodes, its boundary faces, the window's centre (its topmost node).
    pub nodes: Vec<usize>,
    pub faces: Vec<[usize; 3]>,
    pub centre: Point3<f64>,
    /// The truth's displacements.
    pub u: Vec<Vector3<f64>>,
    /// The deep nodes.
    pub deep: Vec<usize>,
}

pub fn regions() -> PathBuf {
    root().join("fixtures/mni152-regions")
}

/// The bell-shaped sag of node `x`: along −z, or tilted `tilt` degrees from it towards +x
/// (a head turned so that gravity meets the window at an angle).
fn bell(x: &Point3<f64>, centre: &Point3<f64>, tilt: f64) -> Vector3<f64> {
    let rho2 = (x.x - centre.x).powi(2) + (x.y - centre.y).powi(2);
    let (s, c) = tilt.to_radians().sin_cos();
    Vector3::new(s, 0.0, -c) * BELL_DEPTH * (-rho2 / (2.0 * BELL_WIDTH * BELL_WIDTH)).exp()
}

/// The regions scene's text (its materials, FIXED, contact, solver) with its craniotomy
/// boundary replaced by `craniotomy` (TOML lines), its mesh and skull found in `mesh_dir`.
pub fn scene_text(craniotomy: &str, mesh_dir: &str) -> String {
    let text = std::fs::read_to_string(regions().join("scene.toml")).expect("the regions scene");
    let cut = text.find("# The MNI152 demo's craniotomy").expect("the craniotomy boundary");
    let contact = text.find("[contact]").expect("the contact table");
    let head = text[..cut].replace("\"brain.inp\"", &format!("\"{mesh_dir}/brain.inp\""));
    let tail = text[contact..].replace("\"skull.off\"", &format!("\"{mesh_dir}/skull.off\""));
    format!("{head}{craniotomy}\n{tail}")
}

/// Solves the truth (in `dir`, where its scene and boundary file go; the scene finds the
/// regions mesh in `mesh_dir`).
pub fn truth(dir: &Path, mesh_dir: &str) -> Result<Truth, String> {
    truth_tilted(dir, mesh_dir, 0.0)
}

/// The truth with its sag tilted `tilt` degrees off −z (towards +x).
pub fn truth_tilted(dir: &Path, mesh_dir: &str, tilt: f64) -> Result<Truth, String> {
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let base = Prepared::load(&regions().join("scene.toml")).map_err(|e| e.to_string())?;
    let mesh = base.mesh.clone();
    let skull = base.skull.clone().ok_or("the regions scene has a skull")?;
    let nodes = mesh.node_set("CRANIOTOMY").ok_or("CRANIOTOMY")?.to_vec();
    let centre = *nodes.iter().map(|&a| &mesh.nodes[a]).max_by(|a, b| a.z.total_cmp(&b.z)).unwrap();
    let mut csv = String::from("node_id,ux,uy,uz\n");
    for &a in &nodes {
        let d = bell(&mesh.nodes[a], &centre, tilt);
        writeln!(csv, "{},{:?},{:?},{:?}", mesh.node_ids[a], d.x, d.y, d.z).unwrap();
    }
    crate::util::write(&dir.join("truth-boundary.csv"), &csv)?;
    let boundary = format!(
        "# The truth: the craniotomy sags in a bell {BELL_DEPTH} mm deep, {BELL_WIDTH} mm wide{} \
         (truth-boundary.csv).\n[[boundary]]\nnset = \"CRANIOTOMY\"\n\
         displacement_file = \"truth-boundary.csv\"\n",
        if tilt == 0.0 { String::new() } else { format!(", {tilt} degrees off -z") }
    );
    let scene = dir.join("scene-truth.toml");
    crate::util::write(&scene, &scene_text(&boundary, mesh_dir))?;
    let u = solve(&scene)?.u;
    let mut csv = String::from("node_id,ux,uy,uz\n");
    for (id, d) in mesh.node_ids.iter().zip(&u) {
        writeln!(csv, "{id},{:?},{:?},{:?}", d.x, d.y, d.z).unwrap();
    }
    crate::util::write(&dir.join("truth.csv"), &csv)?;
    let member: Vec<bool> = (0..mesh.nodes.len()).map(|a| nodes.contains(&a)).collect();
    let faces = patch(&mesh, &member);
    let deep = (0..mesh.nodes.len())
        .filter(|&a| nodes.iter().all(|&c| (mesh.nodes[a] - mesh.nodes[c]).norm() > DEEP))
        .collect();
    Ok(Truth { mesh, skull, nodes, faces, centre, u, deep })
}

/// The boundary faces with all nodes in `member`.
pub(super) fn patch(mesh: &Mesh, member: &[bool]) -> Vec<[usize; 3]> {
    let b = mesh.boundary();
    b.surface
        .triangles
        .iter()
        .map(|t| t.map(|k| b.volume_node[k]))
        .filter(|f| f.iter().all(|&a| member[a]))
        .collect()
}

/// A verified solve of a scene.
pub struct Solve {
    pub u: Vec<Vector3<f64>>,
    pub seconds: f64,
    pub iterations: usize,
    pub min_jacobian: f64,
    /// The first measurement's report, when the scene has one.
    pub measurement: Option<bs_scene::measure::MeasurementReport>,
    /// The gravity solved with and its estimates, when the scene has `[gravity]`.
    pub gravity: Option<bs_scene::estimate::GravityReport>,
}

/// A scene's verified displacements and what the solve took.
pub fn solve(scene: &Path) -> Result<Solve, String> {
    let p = Prepared::load(scene).map_err(|e| e.to_string())?;
    let mut run = Run::prepare(p).map_err(|e| e.to_string())?;
    let s = run.solve(&mut |_| {}).map_err(|e| e.to_string())?;
    Ok(Solve {
        seconds: s.solve_seconds,
        iterations: s.solution.report.steps,
        min_jacobian: s.verification.min_jacobian,
        measurement: s.measurements.first().cloned(),
        gravity: s.gravity.clone(),
        u: s.solution.displacements,
    })
}

/// How a case degrades the scan.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    pub sigma: f64,
    /// 1, 0.5 or 0.25 of the window seen.
    pub coverage: f64,
    pub outliers: f64,
    /// Misalignment (mm of translation; with a 1.5° rotation), estimated from bone points.
    pub misalignment: f64,
    pub seed: u64,
    /// `sliding = "free"`: no sliding prior.
    pub free: bool,
}

impl Case {
    /// The first target row: σ 1 mm, half the window, 5 % outliers, 2 mm misalignment with
    /// bone points, seed 47 (fixtures/fit's scan and the gravity study's).
    pub fn target() -> Case {
        Case { sigma: 1.0, coverage: 0.5, outliers: 0.05, misalignment: 2.0, seed: 47, free: false }
    }

    pub fn coverage(&self) -> Coverage {
        let (a, b) =
            (Vector3::new(1.0, 0.3, 0.0).normalize(), Vector3::new(-0.3, 1.0, 0.0).normalize());
        match self.coverage {
            c if c >= 1.0 => Coverage::Full,
            c if c >= 0.5 => Coverage::Half { a },
            _ => Coverage::Quarter { a, b },
        }
    }

    pub fn misalignment(&self, centre: &Point3<f64>) -> Rigid {
        if self.misalignment == 0.0 {
            return Rigid::default();
        }
        let rotation =
            Rotation3::new(Vector3::new(0.4, -1.0, 0.2).normalize() * 1.5f64.to_radians());
        let t = Vector3::new(0.6, 0.5, -0.62).normalize() * self.misalignment;
        // About the window's centre: the 1.5° turn moves the window little, the bone ring more.
        Rigid { rotation, translation: centre.coords + t - rotation * centre.coords }
    }
}

/// The truth's deformed node positions.
pub fn deformed(t: &Truth) -> Vec<Point3<f64>> {
    t.mesh.nodes.iter().zip(&t.u).map(|(x, d)| x + d).collect()
}

/// The centroid of the deformed window (where coverage cuts go through).
pub fn window_centre(t: &Truth) -> Point3<f64> {
    let d = deformed(t);
    synthetic::centroid(&t.faces.iter().map(|f| d[f[0]]).collect::<Vec<_>>())
}

/// Writes the scan of `case` (and bone points when misaligned) into `dir`; returns the
/// scene text of its fit (the regions mesh found in `mesh_dir`).
pub fn write_scan(t: &Truth, case: &Case, dir: &Path, mesh_dir: &str) -> Result<String, String> {
    let deformed = deformed(t);
    let misalign = case.misalignment(&t.centre);
    let window = window_centre(t);
    let params = ScanParams {
        density: DENSITY,
        sigma: case.sigma,
        coverage: case.coverage(),
        outliers: case.outliers,
        outlier_distance: 8.0,
        misalignment: misalign,
        seed: case.seed,
    };
    let points = synthetic::scan(&deformed, &t.faces, &window, &params);
    write_points(&dir.join("scan.csv"), &points)?;
    let sigma = case.sigma.max(0.1);
    let mut m =
        format!("[[measurement]]\npoints = \"scan.csv\"\nnset = \"CRANIOTOMY\"\nsigma = {sigma}\n");
    if case.free {
        m += "sliding = \"free\"\n";
    }
    if case.misalignment > 0.0 {
        let bone = bone_points(t, case.seed + 1);
        let bone = synthetic::perturb(&bone, case.sigma, &misalign, case.seed + 2);
        write_points(&dir.join("bone.csv"), &bone)?;
        m += "skull_points = \"bone.csv\"\nrigid = true\n";
    }
    let head = format!(
        "# The exposed surface as scanned (fixtures/fit: sigma {} mm, {} % of the window, {} % \
         outliers, {} mm misalignment): fitted, not imposed.\n",
        case.sigma,
        case.coverage * 100.0,
        case.outliers * 100.0,
        case.misalignment
    );
    Ok(scene_text(&format!("{head}{m}"), mesh_dir))
}

/// Points on the skull in a ring around the window (bone the scan sees).
fn bone_points(t: &Truth, seed: u64) -> Vec<Point3<f64>> {
    let rho = |p: &Point3<f64>| ((p.x - t.centre.x).powi(2) + (p.y - t.centre.y).powi(2)).sqrt();
    let window = t.nodes.iter().map(|&a| rho(&t.mesh.nodes[a])).fold(0.0, f64::max);
    let s = &t.skull;
    let ring: Vec<[usize; 3]> = s
        .triangles
        .iter()
        .copied()
        .filter(|f| {
            let c =
                Point3::from(f.iter().map(|&k| s.vertices[k].coords).sum::<Vector3<f64>>() / 3.0);
            (window + 2.0..window + 15.0).contains(&rho(&c)) && c.z > t.centre.z - 40.0
        })
        .collect();
    let mut rng = bs_mesh::rng::SplitMix64::new(seed);
    synthetic::sample_surface(&s.vertices, &ring, BONE_DENSITY, &mut rng)
}

pub fn write_points(path: &Path, points: &[Point3<f64>]) -> Result<(), String> {
    let mut s = String::from("x,y,z\n");
    for p in points {
        writeln!(s, "{:?},{:?},{:?}", p.x, p.y, p.z).unwrap();
    }
    crate::util::write(path, &s)
}

/// Mean, 95th percentile and largest error at the deep nodes.
pub fn deep_error(t: &Truth, u: &[Vector3<f64>]) -> (f64, f64, f64) {
    let mut e: Vec<f64> = t.deep.iter().map(|&a| (u[a] - t.u[a]).norm()).collect();
    e.sort_by(f64::total_cmp);
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    let p95 = e[((e.len() as f64 * 0.95) as usize).min(e.len() - 1)];
    (mean, p95, *e.last().unwrap())
}
