//! `[[region]] resected = true`: the region's elements leave the model. Checked against
//! the same scene on a mesh file written without those elements (the independent path:
//! the file's reader, no resection code), a cavity pressure's loads against the closed
//! cavity's geometry (they sum to zero; their sizes to p × the wall area), and the
//! resections that cannot run, refused by name.
//!
//! The case: a 40 mm Kuhn box (6³ cells), its base held, its top pushed 4 mm down; TUMOUR
//! the elements whose centroid lies within 9 mm of the centre.

use std::path::{Path, PathBuf};

use bs_mesh::{Mesh, Vector3};
use bs_scene::{Prepared, Run};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-resection-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The 40 mm box with a 9 mm tumour at its centre (element sets TUMOUR and BRAIN).
fn box_with_tumour() -> Mesh {
    bs_mesh::structured::box_with_ball(6, 40.0, 9.0, "TUMOUR", "BRAIN")
}

const MATERIAL: &str =
    "material = { model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.45 }";

/// A scene on `mesh_file` with the regions `regions` (TOML) and the base held; the top
/// pushed `push` mm down (none when 0).
fn scene(dir: &Path, mesh_file: &str, regions: &str, push: f64) -> PathBuf {
    let top = if push != 0.0 {
        format!("[[boundary]]\nnset = \"TOP\"\ndisplacement = {{ z = {} }}\n", -push)
    } else {
        String::new()
    };
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"{mesh_file}\"\nelement = \"t4\"\n{regions}\
         [[boundary]]\nnset = \"BASE\"\nfix = [\"x\", \"y\", \"z\"]\n{top}[solver]\ntolerance = 1e-6\n"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn region(elset: &str, extra: &str) -> String {
    format!("[[region]]\nelset = \"{elset}\"\n{MATERIAL}\n{extra}")
}

fn solve(path: &Path) -> (Run, Vec<Vector3<f64>>) {
    let mut run = Run::prepare(Prepared::load(path).unwrap()).unwrap();
    let u = run.solve(&mut |_| {}).unwrap().solution.displacements;
    (run, u)
}

#[test]
fn a_resected_region_equals_the_mesh_without_its_elements() {
    let d = tmp("equal");
    let mesh = box_with_tumour();
    bs_mesh::io::write_mesh(&d.join("box.inp"), &mesh, &Default::default()).unwrap();
    let regions = region("BRAIN", "") + &region("TUMOUR", "resected = true\n");
    let (run, resected) = solve(&scene(&d, "box.inp", &regions, 4.0));
    // The independent path: the same nodes, the tumour's elements left out of the file.
    let tumour = mesh.element_sets["TUMOUR"].clone();
    let mut without = mesh.clone();
    let keep: Vec<usize> = (0..mesh.elements.len()).filter(|e| !tumour.contains(e)).collect();
    without.elements = keep.iter().map(|&e| mesh.elements[e]).collect();
    without.element_ids = keep.iter().map(|&e| mesh.element_ids[e]).collect();
    without.element_sets.clear();
    let d2 = tmp("without");
    bs_mesh::io::write_mesh(&d2.join("box.inp"), &without, &Default::default()).unwrap();
    let (_, reference) = solve(&scene(&d2, "box.inp", &region("*", ""), 4.0));
    let diff = resected.iter().zip(&reference).map(|(a, b)| (a - b).amax()).fold(0.0, f64::max);
    assert!(diff < 1e-9, "{diff}");
    // The cavity is a free surface: the push squeezes it (its walls move), and the nodes
    // inside the tumour, in no element now, are held.
    let r = run.prepared.resection.as_ref().unwrap();
    assert_eq!(r.elements, tumour.len());
    assert!(!r.orphans.is_empty() && r.orphans.iter().all(|&n| resected[n] == Vector3::zeros()));
    let moved = r.walls.iter().flat_map(|w| w.0).map(|n| resected[n].norm()).fold(0.0, f64::max);
    assert!(moved > 0.5, "{moved}");
}

#[test]
fn a_cavity_pressure_loads_the_walls_with_no_resultant_and_its_work_inflates_the_cavity() {
    let d = tmp("pressure");
    bs_mesh::io::write_mesh(&d.join("box.inp"), &box_with_tumour(), &Default::default()).unwrap();
    let p = 200.0; // Pa
    let regions = region("BRAIN", "")
        + &region("TUMOUR", &format!("resected = true\ncavity_pressure = {p}\n"));
    let (run, u) = solve(&scene(&d, "box.inp", &regions, 0.0));
    let walls = &run.prepared.resection.as_ref().unwrap().walls;
    let x = &run.prepared.mesh.nodes;
    let area: f64 = walls
        .iter()
        .map(|(t, _)| (x[t[1]] - x[t[0]]).cross(&(x[t[2]] - x[t[0]])).norm() / 2.0)
        .sum();
    let f = run.composed.loads.forces();
    let total: Vector3<f64> = f.iter().sum();
    // A closed cavity: the pressure's resultant vanishes (Σ A n = 0 over a closed surface).
    assert!(total.norm() < 1e-9 * p * area, "{total}");
    // Its virtual work on the positions, Σ f·X = p Σ A (−n)·c = 3 p V (the divergence
    // theorem over the cavity's closed, flat-faced surface, each triangle's load shared by
    // its three nodes): V the volume of the removed elements, counted on the input mesh.
    let mesh = box_with_tumour();
    let volume: f64 =
        mesh.element_sets["TUMOUR"].iter().map(|&e| mesh.element_volume(e)).sum::<f64>();
    let work: f64 = f.iter().zip(x).map(|(fi, xi)| fi.dot(&xi.coords)).sum();
    assert!((work - 3.0 * p * volume).abs() < 1e-9 * p * volume, "{work} vs {}", 3.0 * p * volume);
    let centre = Vector3::new(20.0, 20.0, 20.0);
    // The cavity grows: its wall nodes move away from the centre.
    let radial: f64 =
        walls.iter().flat_map(|w| w.0).map(|n| u[n].dot(&(x[n].coords - centre).normalize())).sum();
    assert!(radial > 0.0, "{radial}");
}

fn refusal(name: &str, regions: &str, push: f64, extra: &str) -> String {
    let d = tmp(name);
    bs_mesh::io::write_mesh(&d.join("box.inp"), &box_with_tumour(), &Default::default()).unwrap();
    let path = scene(&d, "box.inp", regions, push);
    if !extra.is_empty() {
        let text = std::fs::read_to_string(&path).unwrap() + extra;
        std::fs::write(&path, text).unwrap();
    }
    Prepared::load(&path).map(|_| ()).unwrap_err().to_string()
}

#[test]
fn resections_that_cannot_run_are_refused_by_name() {
    let e = refusal("all", &region("*", "resected = true\n"), 4.0, "");
    assert!(e.contains("removes every element"), "{e}");
    let e =
        refusal("missing", &(region("BRAIN", "") + &region("TUMOR", "resected = true\n")), 4.0, "");
    assert!(e.contains("TUMOR") && e.contains("no such element set"), "{e}");
    let e = refusal(
        "pressure",
        &(region("BRAIN", "") + &region("TUMOUR", "cavity_pressure = 10.0\n")),
        4.0,
        "",
    );
    assert!(e.contains("cavity_pressure goes with resected"), "{e}");
    // Cut the box in two with a resected slab: the upper part has no held node, no skull.
    let d = tmp("slab");
    let mut mesh = box_with_tumour();
    let slab: Vec<usize> = (0..mesh.elements.len())
        .filter(|&e| {
            let z = mesh.elements[e].nodes().iter().map(|&n| mesh.nodes[n].z).sum::<f64>() / 4.0;
            (20.0..26.7).contains(&z)
        })
        .collect();
    let rest: Vec<usize> = (0..mesh.elements.len()).filter(|e| !slab.contains(e)).collect();
    mesh.element_sets = [("SLAB".to_string(), slab), ("REST".to_string(), rest)].into();
    bs_mesh::io::write_mesh(&d.join("box.inp"), &mesh, &Default::default()).unwrap();
    let regions = region("REST", "") + &region("SLAB", "resected = true\ncavity_pressure = 5.0\n");
    let e = Prepared::load(&scene(&d, "box.inp", &regions, 0.0)).unwrap_err().to_string();
    assert!(e.contains("has no held node") && e.contains("'SLAB'"), "{e}");
}

#[test]
fn a_region_resected_in_a_session_equals_a_cold_run_of_the_resected_scene() {
    let d = tmp("session");
    bs_mesh::io::write_mesh(&d.join("box.inp"), &box_with_tumour(), &Default::default()).unwrap();
    let intact = region("BRAIN", "") + &region("TUMOUR", "");
    let mut session =
        bs_scene::Session::new(Prepared::load(&scene(&d, "box.inp", &intact, 4.0)).unwrap())
            .unwrap();
    session.solve(&mut |_| {}).unwrap();
    assert_eq!(session.regions(), vec!["BRAIN", "TUMOUR"]);
    let before = session.displacements().to_vec();
    let e = session.resect("TUMOR", &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("TUMOR") && e.contains("BRAIN, TUMOUR"), "{e}");
    assert_eq!(session.displacements(), &before[..]);
    let warm = session.resect("TUMOUR", &mut |_| {}).unwrap().solution.displacements;
    let d2 = tmp("session-cold");
    bs_mesh::io::write_mesh(&d2.join("box.inp"), &box_with_tumour(), &Default::default()).unwrap();
    let resected = region("BRAIN", "") + &region("TUMOUR", "resected = true\n");
    let (_, cold) = solve(&scene(&d2, "box.inp", &resected, 4.0));
    // Both at the scene's 1e-6 mm tolerance, converging superlinearly: 1e-5 mm.
    let diff = warm.iter().zip(&cold).map(|(a, b)| (a - b).amax()).fold(0.0, f64::max);
    assert!(diff < 1e-5, "{diff}");
    // The push squeezed the intact tumour; the cavity lets the box give more under the same
    // push (the top's reaction falls): the answers differ.
    let change = warm.iter().zip(&before).map(|(a, b)| (a - b).amax()).fold(0.0, f64::max);
    assert!(change > 0.1, "{change}");
    assert_eq!(session.regions(), vec!["BRAIN"]);
    // Resecting the rest would remove everything: refused, the session unchanged.
    let e = session.resect("BRAIN", &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("removes every element"), "{e}");
    assert_eq!(session.displacements(), &warm[..]);
}
