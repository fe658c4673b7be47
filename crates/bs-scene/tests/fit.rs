//! `[[measurement]]`: scanned surfaces fitted with the model, through `Prepared::load` and
//! `Run`, the path `check` and `run` share. Against a closed form (a box compressed by the
//! scan of a plane), against the truth of `fixtures/fit` (written by `cargo xtask fit
//! fixture`), and with the bad inputs a user meets.

use std::path::{Path, PathBuf};

use bs_mesh::{Mesh, Point3, Vector3};
use bs_scene::{Prepared, Run, SceneError};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-fit-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A 40 mm Kuhn box (5³ nodes) with node sets XMIN, YMIN, ZMIN, ZMAX (its faces), as
/// box.inp in `dir`.
fn box_mesh(dir: &Path) -> Mesh {
    let mut mesh = bs_mesh::structured::box_mesh(4, 40.0, true);
    for (name, axis, value) in
        [("XMIN", 0, 0.0), ("YMIN", 1, 0.0), ("ZMIN", 2, 0.0), ("ZMAX", 2, 40.0), ("MID", 2, 20.0)]
    {
        let nodes = (0..mesh.nodes.len()).filter(|&n| mesh.nodes[n][axis] == value).collect();
        mesh.node_sets.insert(name.into(), nodes);
    }
    bs_mesh::io::write_mesh(&dir.join("box.inp"), &mesh, &Default::default()).unwrap();
    bs_mesh::io::read_mesh(&dir.join("box.inp")).unwrap()
}

/// The box held on its symmetry planes, with `measurement` appended.
fn scene(dir: &Path, measurement: &str) -> PathBuf {
    box_mesh(dir);
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"box.inp\"\nelement = \"t4\"\n[[region]]\nelset = \"*\"\n\
         material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.3 }}\n\
         [[boundary]]\nnset = \"XMIN\"\nfix = [\"x\"]\n[[boundary]]\nnset = \"YMIN\"\nfix = [\"y\"]\n\
         [[boundary]]\nnset = \"ZMIN\"\nfix = [\"z\"]\n[solver]\ntolerance = 1e-9\n{measurement}"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// A grid of points on the plane z = `z`, spacing 1 mm, over [−8, 48]² (beyond the box's
/// 40 mm top, so that every part of the top is covered all around).
fn plane_points(z: f64) -> String {
    let mut s = String::from("x,y,z\n");
    for j in 0..=56 {
        for i in 0..=56 {
            s += &format!("{},{},{z}\n", i as f64 - 8.0, j as f64 - 8.0);
        }
    }
    s
}

/// The Cauchy stress σ₃₃ of a decoupled Neo-Hookean body in uniaxial stress with axial
/// stretch `lambda` (lateral stretch from bs-material's closed form).
fn uniaxial_sigma(lambda: f64, mu: f64, kappa: f64) -> f64 {
    let l = bs_material::closed_form::neo_hookean_uniaxial_lateral_stretch(lambda, mu, kappa)
        .expect("bracketed");
    let j = l * l * lambda;
    let s = j.powf(-2.0 / 3.0);
    let i1 = s * (2.0 * l * l + lambda * lambda);
    mu / j * (s * lambda * lambda - i1 / 3.0) + kappa * (j - 1.0)
}

/// The scan of a plane 4 mm below the box's top compresses the box uniaxially (sliding
/// free: the top expands sideways as the closed form says): the answer
/// is homogeneous, `u = ((l − 1)x, (l − 1)y, (λ − 1)z)`, with the top where the data's
/// pull balances the stress, `κ (40λ − 36) = −σ₃₃(λ) l²` (κ the data stiffness the report
/// gives, per reference area; the points lie exactly on the plane, so every scan plane is
/// exact).
#[test]
fn a_scanned_plane_compresses_a_box_as_the_closed_form_says() {
    let dir = tmp("uniaxial");
    std::fs::write(dir.join("scan.csv"), plane_points(36.0)).unwrap();
    let path = scene(
        &dir,
        "[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 0.01\nsliding = \"free\"\n",
    );
    let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    let solved = run.solve(&mut |_| {}).unwrap();
    let kappa_data = solved.measurements[0].stiffness;
    let (e, nu) = (3000.0, 0.3);
    let (mu, kappa) = (e / (2.0 * (1.0 + nu)), e / (3.0 * (1.0 - 2.0 * nu)));
    let mesh = &run.prepared.mesh;
    let u = &solved.solution.displacements;
    // The axial stretch the fit reached, from the top's corner.
    let top =
        (0..mesh.nodes.len()).find(|&n| mesh.nodes[n] == Point3::new(40.0, 40.0, 40.0)).unwrap();
    let lambda = 1.0 + u[top].z / 40.0;
    let l =
        bs_material::closed_form::neo_hookean_uniaxial_lateral_stretch(lambda, mu, kappa).unwrap();
    // Homogeneous: exact for linear tetrahedra, to the solver's tolerance (1e-9 mm).
    let worst = mesh
        .nodes
        .iter()
        .zip(u)
        .map(|(p, d)| {
            let exact = Vector3::new((l - 1.0) * p.x, (l - 1.0) * p.y, (lambda - 1.0) * p.z);
            (d - exact).amax()
        })
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "largest deviation from a homogeneous field {worst:e} mm");
    // The data's pull balances the stress: the springs act per reference area, the stress
    // on the deformed top, `κ (40λ − 36) = −σ₃₃(λ) l²`, to the solver's tolerance.
    let pull = kappa_data * (40.0 * lambda - 36.0);
    let stress = uniaxial_sigma(lambda, mu, kappa) * l * l;
    assert!(stress < 0.0 && (pull + stress).abs() < 1e-6 * stress.abs(), "{pull} vs {stress}");
    // And the data hold the top within a small fraction of the 4 mm they ask.
    assert!(40.0 * lambda - 36.0 < 0.05, "λ = {lambda}");
    let m = &solved.measurements[0];
    // The points over the top (41²) are inliers; the rest, beyond its edges, closest to its
    // border: no evidence about it.
    assert_eq!((m.inliers, m.outliers, m.border, m.far), (1681, 0, m.points - 1681, 0));
    assert!(m.rms_residual < 1e-6 + 40.0 * lambda - 36.0, "{m:?}");
}

/// The checked-in fixture (σ = 1 mm, half of the window scanned, 5 % outliers, a 2 mm
/// misalignment with bone points): the fit's error at the deep nodes stays where
/// `cargo xtask fit study` measured it (mean 0.69 mm, p95 1.33; no correction: 1.71), no
/// element comes near inversion, and the same scan read from .ply gives the same answer.
/// The sliding prior leaves motion along the sag direction free: the box on rollers (its
/// four sides held normal to themselves) compressed by the scan of a plane 4 mm below its
/// top is in confined compression, `u = (0, 0, (λ − 1) z)` with `κ (40λ − 36) = −σ₃₃(λ)`
/// (F = diag(1, 1, λ)), whatever the prior's stiffness; and on the unconfined box the prior
/// holds the top's sideways expansion below what free sliding gives.
#[test]
fn the_sliding_prior_leaves_the_sag_direction_free() {
    let dir = tmp("confined");
    std::fs::write(dir.join("scan.csv"), plane_points(36.0)).unwrap();
    let mut mesh = box_mesh(&dir);
    for (name, axis) in [("XMAX", 0), ("YMAX", 1)] {
        let nodes = (0..mesh.nodes.len()).filter(|&n| mesh.nodes[n][axis] == 40.0).collect();
        mesh.node_sets.insert(name.into(), nodes);
    }
    bs_mesh::io::write_mesh(&dir.join("box.inp"), &mesh, &Default::default()).unwrap();
    let measurement = "[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 0.01\n";
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"box.inp\"\nelement = \"t4\"\n[[region]]\nelset = \"*\"\n\
         material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.3 }}\n\
         [[boundary]]\nnset = \"XMIN\"\nfix = [\"x\"]\n[[boundary]]\nnset = \"XMAX\"\nfix = [\"x\"]\n\
         [[boundary]]\nnset = \"YMIN\"\nfix = [\"y\"]\n[[boundary]]\nnset = \"YMAX\"\nfix = [\"y\"]\n\
         [[boundary]]\nnset = \"ZMIN\"\nfix = [\"z\"]\n[solver]\ntolerance = 1e-9\n{measurement}"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    let solved = run.solve(&mut |_| {}).unwrap();
    let kappa_data = solved.measurements[0].stiffness;
    let (e, nu) = (3000.0, 0.3);
    let (mu, kappa) = (e / (2.0 * (1.0 + nu)), e / (3.0 * (1.0 - 2.0 * nu)));
    let u = &solved.solution.displacements;
    let top =
        (0..mesh.nodes.len()).find(|&n| mesh.nodes[n] == Point3::new(20.0, 20.0, 40.0)).unwrap();
    let lambda = 1.0 + u[top].z / 40.0;
    let worst = mesh
        .nodes
        .iter()
        .zip(u)
        .map(|(p, d)| (d - Vector3::new(0.0, 0.0, (lambda - 1.0) * p.z)).amax())
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "largest deviation from confined compression {worst:e} mm");
    // σ₃₃ of F = diag(1, 1, λ): the decoupled Neo-Hookean law, J = λ.
    let s = lambda.powf(-2.0 / 3.0);
    let i1 = s * (2.0 + lambda * lambda);
    let sigma = mu / lambda * (s * lambda * lambda - i1 / 3.0) + kappa * (lambda - 1.0);
    let pull = kappa_data * (40.0 * lambda - 36.0);
    assert!(sigma < 0.0 && (pull + sigma).abs() < 1e-6 * sigma.abs(), "{pull} vs {sigma}");
    // Unconfined (the box of the closed-form test): the prior resists the top's sideways
    // expansion, which free sliding leaves to the elasticity.
    let corner = |extra: &str| {
        let d = tmp(&format!("unconfined{}", extra.len()));
        std::fs::write(d.join("scan.csv"), plane_points(36.0)).unwrap();
        let path = scene(&d, &format!("{measurement}{extra}"));
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        let solved = run.solve(&mut |_| {}).unwrap();
        let mesh = &run.prepared.mesh;
        let c = (0..mesh.nodes.len()).find(|&n| mesh.nodes[n] == Point3::new(40.0, 40.0, 40.0));
        solved.solution.displacements[c.unwrap()]
    };
    let (resisted, free) = (corner(""), corner("sliding = \"free\"\n"));
    assert!(free.x > 0.5 && resisted.x < 0.5 * free.x, "resisted {resisted}, free {free}");
}

#[test]
fn the_fixture_fits_its_truth_and_the_formats_agree() {
    let fixture = root().join("fixtures/fit");
    let solve = |scene: &Path| {
        let mut run = Run::prepare(Prepared::load(scene).unwrap()).unwrap();
        let s = run.solve(&mut |_| {}).unwrap();
        (run.prepared.mesh.clone(), s)
    };
    let (mesh, s) = solve(&fixture.join("scene.toml"));
    let truth = read_displacements(&fixture.join("truth.csv"), &mesh);
    let craniotomy = mesh.node_set("CRANIOTOMY").unwrap();
    let deep: Vec<usize> = (0..mesh.nodes.len())
        .filter(|&a| craniotomy.iter().all(|&c| (mesh.nodes[a] - mesh.nodes[c]).norm() > 15.0))
        .collect();
    let u = &s.solution.displacements;
    let mean =
        |f: &dyn Fn(usize) -> f64| deep.iter().map(|&a| f(a)).sum::<f64>() / deep.len() as f64;
    let error = mean(&|a| (u[a] - truth[a]).norm());
    let none = mean(&|a| truth[a].norm());
    // The fit study's target row (the same scan): 0.589 mm against 1.71 uncorrected, the
    // measurement issue's target 0.6 mm (0.69 without the sliding prior).
    assert!(error < 0.6 && none > 1.6, "deep error {error:.3} mm (no correction {none:.3})");
    assert!(s.verification.min_jacobian > 0.8, "{}", s.verification.min_jacobian);
    let m = &s.measurements[0];
    let rigid = m.rigid.as_ref().expect("the fixture estimates the misalignment");
    assert!(rigid.bone_rms_after < 1.2 && rigid.bone_rms_before > 1.5, "{rigid:?}");
    // The same scan as .ply: the same points in the same order, the same answer.
    let text = std::fs::read_to_string(fixture.join("scene.toml")).unwrap();
    let dir = tmp("ply");
    let moved = text
        .replace("points = \"scan.csv\"", &format!("points = {:?}", fixture.join("scan.ply")))
        .replace(
            "skull_points = \"bone.csv\"",
            &format!("skull_points = {:?}", fixture.join("bone.csv")),
        )
        .replace(
            "\"../mni152-regions/",
            &format!("\"{}/", root().join("fixtures/mni152-regions").display()),
        );
    std::fs::write(dir.join("scene.toml"), moved).unwrap();
    let (_, p) = solve(&dir.join("scene.toml"));
    assert_eq!(p.solution.displacements, s.solution.displacements);
}

fn read_displacements(path: &Path, mesh: &Mesh) -> Vec<Vector3<f64>> {
    let index: std::collections::HashMap<u64, usize> =
        mesh.node_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    let mut u = vec![Vector3::zeros(); mesh.nodes.len()];
    for line in std::fs::read_to_string(path).unwrap().lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        u[index[&(v[0] as u64)]] = Vector3::new(v[1], v[2], v[3]);
    }
    u
}

/// The error `Prepared::load` gives for the box scene with `measurement` (and files).
fn refused(name: &str, files: &[(&str, &str)], measurement: &str) -> String {
    let dir = tmp(name);
    for (f, text) in files {
        std::fs::write(dir.join(f), text).unwrap();
    }
    let path = scene(&dir, measurement);
    match Prepared::load(&path) {
        Ok(_) => panic!("{name}: accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_measurements_are_refused_naming_the_file_line_or_key() {
    let m = |extra: &str| {
        format!("[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 1.0\n{extra}")
    };
    let scan = plane_points(38.0);
    // An empty cloud.
    let e = refused("empty", &[("scan.csv", "x,y,z\n")], &m(""));
    assert!(e.contains("scan.csv") && e.contains("no points"), "{e}");
    // A coordinate that is not a number: the line named.
    let e = refused("nan", &[("scan.csv", "x,y,z\n1,2,3\n4,nope,6\n")], &m(""));
    assert!(e.contains("scan.csv:3"), "{e}");
    let e = refused("inf", &[("scan.csv", "x,y,z\n1,2,inf\n")], &m(""));
    assert!(e.contains("not finite"), "{e}");
    // The scan in the other frame (x and y negated): every point would be an outlier. (A
    // scan over x, y ∈ [−38, −2] at z = 39, within max_distance = 2 of the top only when
    // read with x and y negated.)
    let mirrored: String = std::iter::once("x,y,z\n".to_string())
        .chain((0..=36).flat_map(|j| {
            (0..=36).map(move |i| format!("{},{},39\n", -2.0 - i as f64, -2.0 - j as f64))
        }))
        .collect();
    let lps: String = mirrored
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                return format!("{l}\n");
            }
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            format!("{},{},{}\n", v[0], v[1], v[2])
        })
        .collect();
    let e = refused("frame", &[("scan.csv", lps.as_str())], &m("max_distance = 2.0\n"));
    assert!(e.contains("every point would be an outlier") && e.contains("LPS"), "{e}");
    // The scan in metres.
    let metres: String = scan
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                return format!("{l}\n");
            }
            let v: Vec<f64> = l.split(',').map(|x| x.parse::<f64>().unwrap() / 1000.0).collect();
            format!("{},{},{}\n", v[0], v[1], v[2])
        })
        .collect();
    let e = refused("units", &[("scan.csv", metres.as_str())], &m(""));
    assert!(e.contains("metres"), "{e}");
    // sigma ≤ 0.
    let e = refused(
        "sigma",
        &[("scan.csv", scan.as_str())],
        &m("").replace("sigma = 1.0", "sigma = 0.0"),
    );
    assert!(e.contains("sigma must be positive"), "{e}");
    // A node set inside the brain: no boundary face.
    let e = refused("inside", &[("scan.csv", scan.as_str())], &m("").replace("ZMAX", "MID"));
    assert!(e.contains("no boundary face") && e.contains("MID"), "{e}");
    // rigid without bone points.
    let e = refused("rigid", &[("scan.csv", scan.as_str())], &m("rigid = true\n"));
    assert!(e.contains("needs skull_points"), "{e}");
    // Bone points without a skull to register them to.
    let e = refused(
        "bone",
        &[("scan.csv", scan.as_str()), ("bone.csv", scan.as_str())],
        &m("skull_points = \"bone.csv\"\nrigid = true\n"),
    );
    assert!(e.contains("no [contact] skull"), "{e}");
    // A misspelt key.
    let e = refused("key", &[("scan.csv", scan.as_str())], &m("sgima = 2\n"));
    assert!(e.contains("sgima"), "{e}");
    // The sliding prior: a zero sag direction, a sag direction with no prior, a value that
    // is not one of the two.
    let e = refused("sag0", &[("scan.csv", scan.as_str())], &m("sag_direction = [0, 0, 0]\n"));
    assert!(e.contains("sag_direction must be a non-zero vector"), "{e}");
    let e = refused(
        "sagfree",
        &[("scan.csv", scan.as_str())],
        &m("sliding = \"free\"\nsag_direction = [0, 0, -1]\n"),
    );
    assert!(e.contains("with sliding = \"free\" there is no prior"), "{e}");
    let e = refused("sliding", &[("scan.csv", scan.as_str())], &m("sliding = \"frictionless\"\n"));
    assert!(e.contains("frictionless") && e.contains("resisted"), "{e}");
}

/// A measured node that a boundary moves is the boundary's: refused; a symmetry plane's
/// zero component is not (the box's top edges lie on XMIN and YMIN).
#[test]
fn a_measured_node_moved_by_a_boundary_is_refused() {
    let dir = tmp("moved");
    std::fs::write(dir.join("scan.csv"), plane_points(38.0)).unwrap();
    let path = scene(
        &dir,
        "[[boundary]]\nnset = \"ZMAX\"\ndisplacement = { z = -1.0 }\n[[measurement]]\npoints = \
         \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 1.0\n",
    );
    match Prepared::load(&path) {
        Err(SceneError::Set { set, message, .. }) => {
            assert_eq!(set, "ZMAX");
            assert!(message.contains("also moved or held"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    let _ = Point3::<f64>::origin();
}

/// Dynamic Relaxation takes the data as an external force and reaches the answer
/// Newton–Krylov reaches (both to 1e-6 mm of their own answers).
#[test]
fn dynamic_relaxation_fits_the_same_answer() {
    let dir = tmp("dr");
    std::fs::write(dir.join("scan.csv"), plane_points(36.0)).unwrap();
    let m = "[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 0.01\n";
    let path = scene(&dir, m);
    let solve = |text: &str| {
        std::fs::write(&path, text).unwrap();
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        run.solve(&mut |_| {}).unwrap().solution.displacements
    };
    let text =
        std::fs::read_to_string(&path).unwrap().replace("tolerance = 1e-9", "tolerance = 1e-6");
    let nk = solve(&text);
    let dr = solve(&text.replace("[solver]", "[solver]\nkind = \"dr\""));
    let worst = nk.iter().zip(&dr).map(|(a, b)| (a - b).amax()).fold(0.0, f64::max);
    assert!(worst < 1e-4, "DR and Newton-Krylov differ by {worst:e} mm");
}

/// Gravity is the prior a scan corrects. The laterally confined column of `fixtures/column`
/// (80 mm, T4ANP, 16 layers, dry) settles 2.85 mm under its own weight; a scan of its top
/// 2 mm below the reference top says it settled less. The fit holds the top up with a
/// uniform traction `t = κ (Z_top − z_scan)` per reference area (κ the data stiffness the
/// report gives; the plane is exact), so every section carries the weight above it plus
/// that traction: `P₃₃(Z) = −κ (H + u(H) − z_scan) − w (H − Z)`, whose closed form
/// (`confined_column_displacement` with that stress at the top, `t` found by bisection)
/// the answer must meet. Tolerance: the element's own error under gravity alone on this
/// mesh (measured here, about 4e-3 of the settlement, `cargo xtask validate`'s column
/// rows), doubled, plus the solver's.
#[test]
fn gravity_is_the_prior_a_scan_of_the_top_corrects() {
    use bs_material::closed_form::confined_column_displacement;
    let dir = tmp("column");
    let (height, scan_z) = (80.0, 78.0);
    let mut pts = String::from("x,y,z\n");
    for j in 0..=40 {
        for i in 0..=40 {
            pts += &format!("{},{},{scan_z}\n", i - 10, j - 10);
        }
    }
    std::fs::write(dir.join("scan.csv"), pts).unwrap();
    let mesh = root().join("fixtures/column/column-t4-16.inp");
    let scene = format!(
        "units = \"mm\"\n[mesh]\nfile = \"{}\"\nelement = \"t4anp\"\n[[region]]\nelset = \"*\"\n\
         material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.45, \
         density = 1040.0 }}\n[[boundary]]\nnset = \"XSIDES\"\nfix = [\"x\"]\n[[boundary]]\n\
         nset = \"YSIDES\"\nfix = [\"y\"]\n[[boundary]]\nnset = \"BASE\"\nfix = [\"z\"]\n\
         [gravity]\ndirection = [0.0, 0.0, -1.0]\nacceleration = 9.81\n[solver]\ntolerance = 1e-8\n",
        mesh.display()
    );
    let measured = "[[measurement]]\npoints = \"scan.csv\"\nnset = \"TOP\"\nsigma = 0.1\n";
    let path = dir.join("scene.toml");
    let solve = |text: &str| {
        std::fs::write(&path, text).unwrap();
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        let solved = run.solve(&mut |_| {}).unwrap();
        let kappa = solved.measurements.first().map(|m| m.stiffness);
        (run.prepared, solved.solution.displacements, kappa)
    };
    let (p, prior, _) = solve(&scene);
    let (_, fitted, kappa) = solve(&format!("{scene}{measured}"));
    let kappa = kappa.unwrap();
    let law = bs_scene::compose::material(&p.scene.regions[0].material).unwrap();
    let w = 1040.0 * 9.81e-3; // N/m³ = Pa/m → Pa/mm
    let z: Vec<f64> = p.mesh.nodes.iter().map(|x| x.z).collect();
    let column = |top: f64| confined_column_displacement(&law, height, &|_| w, top, &z).unwrap();
    let worst = |u: &[Vector3<f64>], exact: &[f64]| {
        u.iter()
            .zip(exact)
            .map(|(u, e)| (u.z - e).abs().max(u.x.abs()).max(u.y.abs()))
            .fold(0.0, f64::max)
    };
    // The element's own error under gravity alone.
    let free = column(0.0);
    let settlement = -free.iter().copied().fold(0.0, f64::min);
    let element_error = worst(&prior, &free);
    assert!(settlement > 2.8 && element_error < 5e-3 * settlement, "{settlement} {element_error}");
    // The top's stress t with t = −κ (H + u(H; t) − z_scan): bisection (u(H) falls as t rises).
    let top_u =
        |t: f64| confined_column_displacement(&law, height, &|_| w, t, &[height]).unwrap()[0];
    let gap = |t: f64| t + kappa * (height + top_u(t) - scan_z);
    let (mut lo, mut hi) = (0.0, 1000.0);
    assert!(gap(lo) < 0.0 && gap(hi) > 0.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if gap(mid) < 0.0 { lo = mid } else { hi = mid }
    }
    let exact = column(0.5 * (lo + hi));
    let err = worst(&fitted, &exact);
    assert!(
        err < 2.0 * element_error + 1e-6,
        "fit vs closed form {err:e} mm (element {element_error:e})"
    );
    // The data moved the answer far beyond that: the top sits near the scan, not where
    // gravity alone put it.
    let top = (0..z.len()).max_by(|&a, &b| z[a].total_cmp(&z[b])).unwrap();
    assert!((height + fitted[top].z - scan_z).abs() < 0.05, "top at {}", height + fitted[top].z);
    let moved = worst(&fitted, &free);
    assert!(moved > 20.0 * err, "the data moved the answer {moved} mm, the error is {err:e} mm");
}

/// The box held at its bottom, with its top (ZMAX) as a landmark measurement's control set
/// and `extra` appended (the landmarks' table or a boundary on the top).
fn held_box(dir: &Path, extra: &str) -> PathBuf {
    box_mesh(dir);
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"box.inp\"\nelement = \"t4\"\n[[region]]\nelset = \"*\"\n\
         material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.45 }}\n\
         [[boundary]]\nnset = \"ZMIN\"\nfix = [\"x\", \"y\", \"z\"]\n[solver]\ntolerance = 1e-8\n{extra}"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Landmark pairs at interior points of the box: their positions and the displacement of
/// the solved truth `u` there (located in the mesh, interpolated linearly as the model's).
fn landmark_pairs(mesh: &Mesh, u: &[Vector3<f64>], outlier: Option<Vector3<f64>>) -> String {
    let locator = bs_mesh::TetLocator::new(mesh).unwrap();
    let mut s = String::from("x,y,z,x2,y2,z2\n");
    for k in 0..12 {
        let p = Point3::new(
            5.0 + 30.0 * ((k * 7) % 12) as f64 / 11.0,
            5.0 + 30.0 * ((k * 5) % 12) as f64 / 11.0,
            8.0 + 2.3 * k as f64,
        );
        let mut q = p + locator.interpolate(u, &p);
        if k == 4 {
            q += outlier.unwrap_or_else(Vector3::zeros);
        }
        s += &format!("{},{},{},{},{},{}\n", p.x, p.y, p.z, q.x, q.y, q.z);
    }
    s
}

/// The largest nodal distance between two displacement fields.
fn largest_difference(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max)
}

/// Landmarks inside the box, made by a solve with the top translated (a field in the fit's
/// basis), are fitted through the top: the fit recovers the truth's displacement at every
/// node (to 1 % of the push: the chord steps use the Jacobian of the reference state), and a
/// landmark 20 mm off is rejected as an outlier, not followed.
#[test]
fn landmarks_fitted_through_the_top_recover_the_push_that_moved_them() {
    let dir = tmp("landmarks");
    let truth = held_box(&dir, "[[boundary]]\nnset = \"ZMAX\"\ndisplacement = [1.0, 0.0, -3.0]\n");
    let mut run = Run::prepare(Prepared::load(&truth).unwrap()).unwrap();
    let u_truth = run.solve(&mut |_| {}).unwrap().solution.displacements;
    let mesh = run.prepared.mesh.clone();
    for (outlier, name) in [(None, "clean"), (Some(Vector3::new(0.0, 20.0, 0.0)), "outlier")] {
        std::fs::write(dir.join("pairs.csv"), landmark_pairs(&mesh, &u_truth, outlier)).unwrap();
        let path = held_box(
            &dir,
            "[[measurement]]\nlandmarks = \"pairs.csv\"\nnset = \"ZMAX\"\nsigma = 0.01\n",
        );
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        let solved = run.solve(&mut |_| {}).unwrap();
        let worst = largest_difference(&solved.solution.displacements, &u_truth);
        assert!(worst < 0.03, "{name}: largest error {worst} mm of a 3.2 mm push");
        let m = &solved.measurements[0];
        assert_eq!(m.kind, bs_scene::measure::MeasurementKind::Landmarks);
        assert_eq!(m.points, 12);
        assert_eq!(m.outliers, usize::from(outlier.is_some()), "{name}: {m:?}");
        assert!(m.rms_residual < 0.03, "{name}: {m:?}");
        assert!(m.solves > bs_fit::boundary_fit::BUMPS + 3, "{name}: {m:?}");
    }
}

/// Landmark files a user gets wrong: a landmark outside the brain names its line; a
/// landmark set held by a boundary, and landmarks beside a scan, are refused.
#[test]
fn bad_landmarks_are_refused_naming_the_file_and_line() {
    let dir = tmp("bad-landmarks");
    let pairs = "x,y,z,x2,y2,z2\n10,10,20,10,10,19\n10,30,30,10,30,29\n60,10,20,60,10,19\n\
                 30,30,10,30,30,9\n";
    std::fs::write(dir.join("pairs.csv"), pairs).unwrap();
    let m = "[[measurement]]\nlandmarks = \"pairs.csv\"\nnset = \"ZMAX\"\nsigma = 1\n";
    let e = Prepared::load(&held_box(&dir, m)).unwrap_err().to_string();
    assert!(e.contains("pairs.csv: line 4") && e.contains("outside the brain mesh"), "{e}");
    let held = format!("{m}[[boundary]]\nnset = \"ZMAX\"\nfix = [\"z\"]\n");
    let e = Prepared::load(&held_box(&dir, &held)).unwrap_err().to_string();
    assert!(e.contains("also held by a [[boundary]]"), "{e}");
    let no_set = "[[measurement]]\nlandmarks = \"pairs.csv\"\nsigma = 1\n";
    let e = Prepared::load(&held_box(&dir, no_set)).unwrap_err().to_string();
    assert!(e.contains("landmarks fitted alone need nset"), "{e}");
}

/// A new scan in a live session is fitted with the session's preparation and lands where a
/// cold run of a scene with that scan lands; an update naming no scanned set is refused and
/// leaves the session where it was.
#[test]
fn a_new_scan_in_a_session_fits_as_a_cold_run_of_it() {
    let dir = tmp("session-scan");
    let fixture = root().join("fixtures/fit");
    let points = bs_mesh::io::points::read_points(&fixture.join("scan.csv")).unwrap();
    // The second scan: the window 1 mm deeper.
    let deeper: Vec<Point3<f64>> = points.iter().map(|p| p - Vector3::new(0.0, 0.0, 1.0)).collect();
    let mut csv = String::from("x,y,z\n");
    for p in &deeper {
        csv += &format!("{:?},{:?},{:?}\n", p.x, p.y, p.z);
    }
    std::fs::write(dir.join("deeper.csv"), csv).unwrap();
    let text = std::fs::read_to_string(fixture.join("scene.toml")).unwrap();
    let regions = root().join("fixtures/mni152-regions");
    let text = text
        .replace("../mni152-regions", &regions.display().to_string())
        .replace("\"scan.csv\"", "\"deeper.csv\"")
        .replace("\"bone.csv\"", &format!("{:?}", fixture.join("bone.csv").display().to_string()));
    std::fs::write(dir.join("scene.toml"), text).unwrap();
    let mut cold = Run::prepare(Prepared::load(&dir.join("scene.toml")).unwrap()).unwrap();
    let cold = cold.solve(&mut |_| {}).unwrap();

    let mut session =
        bs_scene::Session::new(Prepared::load(&fixture.join("scene.toml")).unwrap()).unwrap();
    session.solve(&mut |_| {}).unwrap();
    assert_eq!(session.measured_sets(), ["CRANIOTOMY"]);
    let warm = session.update_points(&[("CRANIOTOMY".into(), deeper)], &mut |_| {}).unwrap();
    let worst = warm
        .solution
        .displacements
        .iter()
        .zip(&cold.solution.displacements)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    // The same fit from the same state: equal to rounding (the session's contact handler
    // has seen other states; 1e-9 mm is far below the solver's 1e-3 mm tolerance).
    assert!(worst < 1e-9, "a session's new scan against a cold run: {worst} mm");
    let m = &warm.measurements[0];
    assert_eq!(m.points, points.len());
    let before = session.displacements().to_vec();
    let e = session.update_points(&[("NOPE".into(), points)], &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("scanned node sets are: CRANIOTOMY"), "{e}");
    assert_eq!(session.displacements(), &before[..]);
}

/// New landmark pairs in a live session are fitted as a cold run of a scene with those
/// pairs (the same fit from the same reference state); a landmark outside the brain and an
/// unknown node set are refused naming them, the session keeping its last good state.
#[test]
fn new_landmarks_in_a_session_fit_as_a_cold_run_of_them() {
    let dir = tmp("session-landmarks");
    let push = |d: &str| format!("[[boundary]]\nnset = \"ZMAX\"\ndisplacement = {d}\n");
    let truth = |d: &str| {
        let path = held_box(&dir, &push(d));
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        let u = run.solve(&mut |_| {}).unwrap().solution.displacements;
        (run.prepared.mesh.clone(), u)
    };
    let (mesh, first) = truth("[1.0, 0.0, -3.0]");
    let (_, second) = truth("[0.0, -1.0, -4.0]");
    std::fs::write(dir.join("pairs.csv"), landmark_pairs(&mesh, &first, None)).unwrap();
    std::fs::write(dir.join("second.csv"), landmark_pairs(&mesh, &second, None)).unwrap();
    let m =
        |f: &str| format!("[[measurement]]\nlandmarks = \"{f}\"\nnset = \"ZMAX\"\nsigma = 0.01\n");
    let cold_path = held_box(&dir, &m("second.csv"));
    let mut cold = Run::prepare(Prepared::load(&cold_path).unwrap()).unwrap();
    let cold = cold.solve(&mut |_| {}).unwrap();

    let path = held_box(&dir, &m("pairs.csv"));
    let mut session = bs_scene::Session::new(Prepared::load(&path).unwrap()).unwrap();
    session.solve(&mut |_| {}).unwrap();
    assert_eq!(session.landmark_sets(), ["ZMAX"]);
    let files = |f: &str| bs_scene::scene::LandmarkFiles::Pairs(dir.join(f));
    let warm = session.update_landmarks("ZMAX", files("second.csv"), &mut |_| {}).unwrap();
    let worst = |a: &[Vector3<f64>], b: &[Vector3<f64>]| {
        a.iter().zip(b).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max)
    };
    let d = worst(&warm.solution.displacements, &cold.solution.displacements);
    assert!(d < 1e-9, "a session's new landmarks against a cold run: {d} mm");
    assert_eq!(warm.measurements[0].rms_residual, cold.measurements[0].rms_residual);
    // The fit followed the second push (within 2 % of its 4.1 mm: the chord steps use the
    // reference state's Jacobian), not the first.
    let off = worst(&warm.solution.displacements, &second);
    assert!(off < 0.02 * 17f64.sqrt(), "{off} mm from the second push");
    assert!(worst(&warm.solution.displacements, &first) > 1.0);
    let before = session.displacements().to_vec();
    let e = session.update_landmarks("NOPE", files("second.csv"), &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("landmark node sets are: ZMAX"), "{e}");
    std::fs::write(
        dir.join("outside.csv"),
        "x,y,z,x2,y2,z2\n10,10,20,10,10,19\n60,10,20,60,10,19\n",
    )
    .unwrap();
    let e = session.update_landmarks("ZMAX", files("outside.csv"), &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("outside.csv: line 3"), "{e}");
    assert_eq!(session.displacements(), &before[..]);
    assert_eq!(session.landmark_pairs("ZMAX").unwrap().pre.len(), 12);
}

/// The confined column of `gravity_is_the_prior_a_scan_of_the_top_corrects` with a fluid
/// below `level` and `[gravity]` extra keys `extra`, its top scanned at `scan_z`.
fn column_scene(dir: &Path, level: f64, acceleration: f64, extra: &str, scan_z: f64) -> PathBuf {
    let mut pts = String::from("x,y,z\n");
    for j in 0..=40 {
        for i in 0..=40 {
            pts += &format!("{},{},{scan_z}\n", i - 10, j - 10);
        }
    }
    std::fs::write(dir.join("scan.csv"), pts).unwrap();
    let mesh = root().join("fixtures/column/column-t4-16.inp");
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"{}\"\nelement = \"t4anp\"\n[[region]]\nelset = \"*\"\n\
         material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.45, \
         density = 1040.0 }}\n[[boundary]]\nnset = \"XSIDES\"\nfix = [\"x\"]\n[[boundary]]\n\
         nset = \"YSIDES\"\nfix = [\"y\"]\n[[boundary]]\nnset = \"BASE\"\nfix = [\"z\"]\n\
         [gravity]\ndirection = [0.0, 0.0, -1.0]\nacceleration = {acceleration:?}\n\
         fluid = {{ density = 1007.0, level = [5.0, 5.0, {level:?}] }}\n{extra}\n\
         [[measurement]]\npoints = \"scan.csv\"\nnset = \"TOP\"\nsigma = 0.1\n\
         [solver]\ntolerance = 1e-8\n",
        mesh.display()
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn the_estimated_level_and_weight_are_those_whose_closed_form_settles_the_top_onto_the_scan() {
    use bs_material::closed_form::confined_column_displacement;
    let dir = tmp("column-estimate");
    let height = 80.0;
    let law = bs_material::Material::neo_hookean(3000.0, 0.45).unwrap();
    // Weight per reference volume (Pa/mm) of the tissue, less the fluid's below the level.
    let top_of = |level: f64, factor: f64| {
        let (w, wf) = (1040.0 * 9.81e-3 * factor, 1007.0 * 9.81e-3 * factor);
        let weight = move |z: f64| if z < level { w - wf } else { w };
        confined_column_displacement(&law, height, &weight, 0.0, &[height]).unwrap()[0]
    };
    // The truth: the fluid stands at z = 30 and the tissue weighs 9.81 m/s²; its top scanned.
    let scan_z = height + top_of(30.0, 1.0);
    // The closed form's settlement and the top's sensitivity to the level (mm per mm).
    let settlement = -top_of(30.0, 1.0);
    let per_mm = (top_of(31.0, 1.0) - top_of(29.0, 1.0)) / 2.0;
    assert!(settlement > 0.5 && per_mm.abs() > 1e-3, "{settlement} {per_mm}");
    let estimate = |level: f64, acceleration: f64, keys: &str| {
        let path = column_scene(&dir, level, acceleration, keys, scan_z);
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        let solved = run.solve(&mut |_| {}).unwrap();
        let g = solved.gravity.expect("the report's gravity");
        assert!(g.data_used && g.note.is_none(), "{g:?}");
        (g, solved.solution.displacements, run.prepared)
    };
    // The scene believes the level 10 mm too high (z = 40); estimated along gravity (−z), the
    // shift is positive downwards: the closed form says 10 mm.
    let (g, u, p) = estimate(40.0, 9.81, "estimate = { level = 15.0 }");
    let e = &g.estimates[0];
    assert_eq!(e.name, "level");
    // The model's own settlement error (below 0.5 % of it: gravity_is_the_prior…), divided
    // by the top's sensitivity to the level, bounds the level's error; three times that.
    let found = 40.0 - e.estimate;
    let bound = 3.0 * 0.005 * settlement / per_mm.abs();
    assert!((found - 30.0).abs() < bound, "level {found} against 30 (bound {bound})");
    // The standard error of a least-squares level from `inliers` points of noise σ = 0.1
    // whose distances move by `per_mm` per mm of level, with the 15 mm prior.
    let data = 0.1 / ((g.inliers as f64).sqrt() * per_mm.abs());
    let expected = 1.0 / (1.0 / (data * data) + 1.0 / 225.0).sqrt();
    assert!(e.determined, "{e:?}");
    assert!(
        (e.standard_error / expected - 1.0).abs() < 0.2,
        "{e:?}: expected {expected} ({} inliers, {per_mm} mm/mm)",
        g.inliers
    );
    // The data then pull the top onto the scan.
    let top = (0..p.mesh.nodes.len())
        .max_by(|&a, &b| p.mesh.nodes[a].z.total_cmp(&p.mesh.nodes[b].z))
        .unwrap();
    assert!((height + u[top].z - scan_z).abs() < 0.02, "top at {}", height + u[top].z);
    // The weight with the level known: the scene's acceleration 20 % low.
    let (g, _, _) = estimate(30.0, 9.81 / 1.2, "estimate = { weight = 0.3 }");
    let e = &g.estimates[0];
    assert_eq!(e.name, "weight");
    // The settlement's relative error (0.5 %) is about the weight's; three times that.
    assert!(
        (1.0 + e.estimate - 1.2).abs() < 3.0 * 0.005 * 1.2,
        "weight factor {}",
        1.0 + e.estimate
    );
}

#[test]
fn a_bad_estimate_is_refused_naming_its_key() {
    let dir = tmp("estimate-bad");
    let bad = |fluid: &str, estimate: &str, measured: bool| {
        let path = column_scene(&dir, 30.0, 9.81, "", 78.0);
        let mut text = std::fs::read_to_string(&path).unwrap();
        text = text.replace("fluid = { density = 1007.0, level = [5.0, 5.0, 30.0] }", fluid);
        text = text.replace("[[measurement]]", &format!("{estimate}\n[[measurement]]"));
        if !measured {
            let cut = text.find("[[measurement]]").unwrap();
            let end = text.find("[solver]").unwrap();
            text.replace_range(cut..end, "");
        }
        std::fs::write(&path, text).unwrap();
        match Prepared::load(&path) {
            Ok(_) => panic!("accepted: {estimate}"),
            Err(e) => e.to_string(),
        }
    };
    let fluid = "fluid = { density = 1007.0, level = [5.0, 5.0, 30.0] }";
    let m = bad(fluid, "estimate = { level = 15.0 }", false);
    assert!(m.contains("estimate (level) needs data") && m.contains("[[measurement]]"), "{m}");
    let m = bad("", "estimate = { level = 15.0 }", true);
    assert!(m.contains("estimate.level") && m.contains("no fluid"), "{m}");
    let m = bad(fluid, "estimate = { level = 0.0 }", true);
    assert!(m.contains("estimate.level = 0") && m.contains("positive"), "{m}");
    let m = bad(fluid, "estimate = { weight = -0.3 }", true);
    assert!(m.contains("estimate.weight = -0.3"), "{m}");
    let m = bad(fluid, "estimate = { levle = 15.0 }", true);
    assert!(m.contains("levle") && m.contains("level"), "{m}");
    let m = bad(fluid, "estimate = { }", true);
    assert!(m.contains("names nothing"), "{m}");
}

/// The column's closed-form displacement (mm, up) at heights `z` with the fluid below
/// `level`, its height and its law those of [`column_scene`].
fn column_at(level: f64, z: &[f64]) -> Vec<f64> {
    use bs_material::closed_form::confined_column_displacement;
    let law = bs_material::Material::neo_hookean(3000.0, 0.45).unwrap();
    let (w, wf) = (1040.0 * 9.81e-3, 1007.0 * 9.81e-3);
    let weight = move |h: f64| if h < level { w - wf } else { w };
    confined_column_displacement(&law, 80.0, &weight, 0.0, z).unwrap()
}

/// The closed form's sensitivity to the level (mm per mm) at heights `z`, about z = 30.
fn column_sensitivity(z: &[f64]) -> Vec<f64> {
    column_at(31.0, z).iter().zip(column_at(29.0, z)).map(|(a, b)| (a - b) / 2.0).collect()
}

/// The heights of the forty landmarks of [`column_with_landmarks`]: 4–74 mm up the column.
fn column_landmark_heights() -> Vec<f64> {
    (0..40).map(|k| 4.0 + 1.8 * k as f64).collect()
}

/// The column of [`column_scene`] believing the level at z = 40 (the truth's at 30),
/// estimated with forty landmarks 4–74 mm up it at their closed-form displacements
/// (σ 0.03) and, with `scan`, its top scanned (σ 0.1); solved.
fn column_with_landmarks(dir: &Path, scan: bool) -> bs_scene::Solved {
    let scan_z = 80.0 + column_at(30.0, &[80.0])[0];
    let heights = column_landmark_heights();
    let u = column_at(30.0, &heights);
    let mut pairs = String::from("x,y,z,x2,y2,z2\n");
    for (k, (z, dz)) in heights.iter().zip(&u).enumerate() {
        let (x, y) = (5.0 + 5.0 * (k % 3) as f64, 5.0 + 5.0 * ((k / 3) % 3) as f64);
        pairs += &format!("{x},{y},{z},{x},{y},{}\n", z + dz);
    }
    std::fs::write(dir.join("pairs.csv"), pairs).unwrap();
    let path = column_scene(dir, 40.0, 9.81, "estimate = { level = 15.0 }", scan_z);
    let mut text = std::fs::read_to_string(&path).unwrap();
    if !scan {
        let cut = text.find("[[measurement]]").unwrap();
        let end = text.find("[solver]").unwrap();
        text.replace_range(cut..end, "");
    }
    let text = text
        .replace("[solver]", "[[measurement]]\nlandmarks = \"pairs.csv\"\nsigma = 0.03\n[solver]");
    std::fs::write(&path, text).unwrap();
    let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    run.solve(&mut |_| {}).unwrap()
}

/// The level found by `g` is within three times the model's settlement error over the
/// top's sensitivity of the truth's (as the scan alone: the_estimated_level_and_weight_…).
fn assert_column_level(g: &bs_scene::estimate::GravityReport) {
    let per_mm = column_sensitivity(&[80.0])[0].abs();
    let found = 40.0 - g.estimates[0].estimate;
    let bound = 3.0 * 0.005 * -column_at(30.0, &[80.0])[0] / per_mm;
    assert!((found - 30.0).abs() < bound, "level {found} against 30 (bound {bound})");
}

/// The least-squares information of the level from the forty landmarks of
/// [`column_with_landmarks`]: each landmark's axial miss moves by the closed form's
/// sensitivity at its height; its lateral misses do not move.
fn landmark_information() -> f64 {
    let heights = column_landmark_heights();
    column_sensitivity(&heights).iter().map(|s| s * s).sum::<f64>() / 0.0009
}

/// Landmarks beside a scan are evidence for the level: the column's top scanned and
/// landmarks inside it at their closed-form displacements, the level estimated from both.
/// The least-squares information of the level is the sum of the scan's and the landmarks',
/// so the standard error is the closed form's of that sum.
#[test]
fn landmarks_beside_the_scan_add_their_closed_form_information_to_the_level() {
    let solved = column_with_landmarks(&tmp("column-landmarks"), true);
    let g = solved.gravity.expect("the report's gravity");
    assert!(g.data_used && g.note.is_none(), "{g:?}");
    assert_eq!(g.landmark_inliers, 40, "{g:?}");
    assert_column_level(&g);
    let per_mm = column_sensitivity(&[80.0])[0].abs();
    // The scan's noise 0.1 mm, the landmarks' 0.03 (so that they matter beside the scan's
    // hundreds of points).
    let scan = g.inliers as f64 * per_mm * per_mm / 0.01;
    let expected = 1.0 / (scan + landmark_information() + 1.0 / 225.0).sqrt();
    let scan_only = 1.0 / (scan + 1.0 / 225.0).sqrt();
    assert!(expected < 0.9 * scan_only, "the landmarks must matter: {expected} {scan_only}");
    let e = &g.estimates[0];
    assert!(
        (e.standard_error / expected - 1.0).abs() < 0.2,
        "{e:?}: expected {expected} (scan alone {scan_only})"
    );
    // The landmarks are reported as measured, not pulled (the scan pulls).
    let m = &solved.measurements[1];
    assert_eq!((m.kind, m.nset.as_str()), (bs_scene::measure::MeasurementKind::Landmarks, ""));
    assert!(m.max_residual < 0.1, "{m:?}");
}

/// Landmarks alone, through no set, are evidence for the level: nothing is prescribed, the
/// level is the closed form's and its standard error the landmarks' information alone; the
/// answer is the model at the estimate, the landmarks on it within their noise.
#[test]
fn landmarks_alone_without_a_set_estimate_the_level_with_their_closed_form_information() {
    let solved = column_with_landmarks(&tmp("column-landmarks-alone"), false);
    let g = solved.gravity.expect("the report's gravity");
    assert!(g.data_used && g.note.is_none(), "{g:?}");
    assert_eq!((g.inliers, g.landmark_inliers), (0, 40), "{g:?}");
    assert_column_level(&g);
    let expected = 1.0 / (landmark_information() + 1.0 / 225.0).sqrt();
    let e = &g.estimates[0];
    assert!(e.determined, "{e:?}");
    assert!((e.standard_error / expected - 1.0).abs() < 0.2, "{e:?}: expected {expected}");
    let m = &solved.measurements[0];
    assert_eq!((m.kind, m.nset.as_str()), (bs_scene::measure::MeasurementKind::Landmarks, ""));
    assert!(m.max_residual < 0.1, "{m:?}");
}

/// Landmarks beside a scan without an estimate, or naming a set, are refused saying why.
#[test]
fn landmarks_beside_a_scan_need_an_estimate_and_no_set() {
    let dir = tmp("column-landmarks-bad");
    std::fs::write(dir.join("pairs.csv"), "x,y,z,x2,y2,z2\n10,10,40,10,10,39\n").unwrap();
    let refused = |estimate: &str, nset: &str| {
        let path = column_scene(&dir, 30.0, 9.81, estimate, 78.0);
        let text = std::fs::read_to_string(&path).unwrap().replace(
            "[solver]",
            &format!("[[measurement]]\nlandmarks = \"pairs.csv\"\n{nset}sigma = 0.1\n[solver]"),
        );
        std::fs::write(&path, text).unwrap();
        Prepared::load(&path).err().map(|e| e.to_string()).unwrap_or_default()
    };
    let m = refused("", "");
    assert!(m.contains("[[measurement]] #2 landmarks") && m.contains("estimate"), "{m}");
    let m = refused("estimate = { level = 15.0 }", "nset = \"TOP\"\n");
    assert!(m.contains("[[measurement]] #2 nset") && m.contains("remove nset"), "{m}");
    assert!(refused("estimate = { level = 15.0 }", "").is_empty());
}

/// The plane's points of [`plane_points`] with isotropic Gaussian noise `sigma` per axis.
fn noisy_plane(z: f64, sigma: f64, rng: &mut bs_mesh::rng::SplitMix64) -> String {
    let mut s = String::from("x,y,z\n");
    for j in 0..=56 {
        for i in 0..=56 {
            let (x, y) = (i as f64 - 8.0, j as f64 - 8.0);
            let [a, b, c] = [rng.normal(), rng.normal(), rng.normal()].map(|v| v * sigma);
            s += &format!("{},{},{}\n", x + a, y + b, z + c);
        }
    }
    s
}

/// σ from the fit's linearised posterior is the spread of the whole nonlinear fit over
/// fresh scans (brute force: 40 fits, each of its own noisy scan of the plane 4 mm below
/// the box's top).
#[test]
fn the_sampled_sigma_is_the_spread_of_the_fit_over_fresh_scans() {
    let dir = tmp("sigma");
    let measurement = "[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 0.5\nsliding = \"free\"\n";
    let mut rng = bs_mesh::rng::SplitMix64::new(11);
    let (fits, mut answers) = (40, Vec::new());
    for _ in 0..fits {
        std::fs::write(dir.join("scan.csv"), noisy_plane(36.0, 0.5, &mut rng)).unwrap();
        let path = scene(&dir, measurement);
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        answers.push(run.solve(&mut |_| {}).unwrap().solution.displacements);
    }
    let n = answers[0].len();
    let mean: Vec<Vector3<f64>> =
        (0..n).map(|a| answers.iter().map(|u| u[a]).sum::<Vector3<f64>>() / fits as f64).collect();
    let spread = |a: usize| {
        let v = answers.iter().map(|u| (u[a] - mean[a]).norm_squared()).sum::<f64>();
        (v / (fits - 1) as f64).sqrt()
    };
    // The last scan's fit, sampled.
    let path = scene(&dir, measurement);
    let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    let solved = run.solve(&mut |_| {}).unwrap();
    let params = bs_scene::uncertainty::UncertaintyParams { samples: 64, ..Default::default() };
    for rtol in [0.0, 1.0, f64::NAN] {
        let bad = bs_scene::uncertainty::UncertaintyParams { rtol, ..params };
        let e = bs_scene::uncertainty::sample(&mut run, &solved, &bad).unwrap_err().to_string();
        assert!(e.contains("relative residual between 0 and 1"), "{rtol}: {e}");
    }
    let u = bs_scene::uncertainty::sample(&mut run, &solved, &params).unwrap();
    assert_eq!(u.parts, ["scan noise"]);
    let top: Vec<usize> = run.prepared.mesh.node_sets["ZMAX"].clone();
    let (brute, sampled) =
        top.iter().fold((0.0, 0.0), |(b, s), &a| (b + spread(a), s + u.total(a)));
    // The noise moves the top by a few hundredths of a millimetre (the data average 41² points).
    assert!(brute > 1e-3 * top.len() as f64, "{brute}");
    // 40 fits and 64 samples: each estimate of σ within about 11 % and 9 % (1/√(2N)), their
    // ratio within ±35 % at 2.5 standard deviations.
    let ratio = sampled / brute;
    assert!((0.7..1.4).contains(&ratio), "sampled {sampled:e} vs the fits' spread {brute:e}");
    // A loose stop's shortfall, measured on the first batch and scaled away: σ with the
    // solves stopped at 0.1 (10 % short here) against σ at 1e-6, the same draws; the
    // scale is estimated from four responses refined to 1e-3, which on the fixtures lands
    // within 2 % of the converged σ (docs/uncertainty.md).
    let at = |run: &mut Run, rtol| {
        let p = bs_scene::uncertainty::UncertaintyParams { samples: 16, rtol, ..params };
        bs_scene::uncertainty::sample(run, &solved, &p).unwrap()
    };
    let (loose, tight) = (at(&mut run, 0.1), at(&mut run, 1e-6));
    let sum = |u: &bs_scene::uncertainty::Uncertainty| top.iter().map(|&a| u.total(a)).sum::<f64>();
    assert_eq!(tight.tolerance_scale, 1.0);
    let (scale, ratio) = (loose.tolerance_scale, sum(&loose) / sum(&tight));
    assert!(scale > 1.05, "the loose stop should fall short: scale {scale}");
    assert!((ratio - 1.0).abs() < 0.03, "scaled σ / converged σ = {ratio} (scale {scale})");
    assert!((ratio / scale - 1.0).abs() > 0.04, "unscaled it would be off: {ratio} / {scale}");
}

/// `--uncertainty` needs something fitted: a scene without measurements is refused,
/// naming why.
#[test]
fn the_uncertainty_of_a_scene_without_a_fit_is_refused() {
    let dir = tmp("sigma-none");
    let path = scene(&dir, "[[boundary]]\nnset = \"ZMAX\"\ndisplacement = [0.0, 0.0, -2.0]\n");
    let run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    let e = bs_scene::uncertainty::check(&run).unwrap_err().to_string();
    assert!(e.contains("--uncertainty") && e.contains("fits nothing"), "{e}");
}

/// Held-out landmarks scale σ by how much more they miss than σ predicts: pairs placed on
/// the fitted answer miss by nothing and leave σ as it is; the same pairs moved by known
/// offsets give the moment estimate of those offsets (`uncertainty/held_out.rs`), and every
/// σ is that factor times the unscaled one (the same draws).
#[test]
fn held_out_landmarks_scale_sigma_by_their_misses() {
    let dir = tmp("sigma-held-out");
    let mut rng = bs_mesh::rng::SplitMix64::new(5);
    std::fs::write(dir.join("scan.csv"), noisy_plane(36.0, 0.5, &mut rng)).unwrap();
    let tau = 0.1;
    let measurement = format!(
        "[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 0.5\nsliding = \"free\"\n\
         [uncertainty]\nheld_out = \"held-out.csv\"\nsigma = {tau:?}\n"
    );
    let path = scene(&dir, &measurement);
    let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    let solved = run.solve(&mut |_| {}).unwrap();
    let u = &solved.solution.displacements;
    let mesh = run.prepared.mesh.clone();
    // Five interior nodes (their material points are the nodes themselves).
    let at = [
        [10.0, 10.0, 30.0],
        [20.0, 20.0, 30.0],
        [30.0, 10.0, 20.0],
        [10.0, 30.0, 30.0],
        [20.0, 10.0, 20.0],
    ];
    let nodes: Vec<usize> = at
        .iter()
        .map(|p| mesh.nodes.iter().position(|x| (x - Point3::from(*p)).norm() < 1e-9).unwrap())
        .collect();
    let offsets =
        [[0.5, 0.0, 0.0], [0.0, -0.4, 0.3], [0.2, 0.2, 0.2], [0.0, 0.0, -0.6], [0.3, -0.3, 0.0]]
            .map(Vector3::from);
    let write = |offset: &dyn Fn(usize) -> Vector3<f64>| {
        let mut s = String::from("x,y,z,x2,y2,z2\n");
        for (k, &a) in nodes.iter().enumerate() {
            let (x, y) = (mesh.nodes[a], mesh.nodes[a] + u[a] + offset(k));
            s += &format!("{:?},{:?},{:?},{:?},{:?},{:?}\n", x.x, x.y, x.z, y.x, y.y, y.z);
        }
        std::fs::write(dir.join("held-out.csv"), s).unwrap();
    };
    let params =
        bs_scene::uncertainty::UncertaintyParams { samples: 16, seed: 3, ..Default::default() };
    write(&|_| Vector3::zeros());
    let plain = bs_scene::uncertainty::sample(&mut run, &solved, &params).unwrap();
    let h = plain.held_out.clone().unwrap();
    assert_eq!(h.landmarks, 5);
    assert!(h.rms_miss < 1e-9, "pairs on the answer miss by {}", h.rms_miss);
    assert_eq!((h.estimate, h.scale), (0.0, 1.0));
    // The posterior's mean tr Σ at the pairs, from what it predicted with their noise.
    let tr = h.rms_predicted.powi(2) - 3.0 * tau * tau;
    assert!(tr > 0.0, "{tr}");
    write(&|k| offsets[k]);
    let scaled = bs_scene::uncertainty::sample(&mut run, &solved, &params).unwrap();
    let h = scaled.held_out.clone().unwrap();
    let e2: f64 = offsets.iter().map(|d| d.norm_squared()).sum();
    let expect = ((e2 - 15.0 * tau * tau) / (5.0 * tr)).sqrt();
    assert!((h.estimate / expect - 1.0).abs() < 1e-6, "{} vs {expect}", h.estimate);
    assert!(h.scale > 1.0 && h.scale == h.estimate);
    assert!((h.rms_miss - (e2 / 5.0).sqrt()).abs() < 1e-9);
    for a in 0..u.len() {
        let (s, p) = (scaled.total(a), plain.total(a));
        assert!((s - h.scale * p).abs() <= 1e-6 * s.max(1e-12), "node {a}: {s} vs {p}");
    }
    assert!(scaled.parts.iter().any(|p| p.contains("5 held-out landmarks")), "{:?}", scaled.parts);
}

/// A scan the box cannot reach: the plane 10 mm below the box's held bottom, at σ 0.01 mm
/// with the sliding prior, pulls the top through the bottom and inverts elements (free
/// sliding lets the top fold around the box instead). The box without the data (nothing
/// else loads it) is at rest, so the run does not fail: the answer is that prior's,
/// verified without the data, the report says why (the measurement, the element its pull
/// inverts and where), and σ is refused (nothing was fitted).
#[test]
fn a_pull_that_cannot_be_carried_gives_the_priors_answer_and_says_why() {
    let dir = tmp("unreachable");
    std::fs::write(dir.join("scan.csv"), plane_points(-10.0)).unwrap();
    let path = scene(
        &dir,
        "[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 0.01\nmax_distance = 60.0\n",
    );
    let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    let solved = run.solve(&mut |_| {}).unwrap();
    let why = solved.data_unused.clone().expect("the data were not used");
    let element = why.split("inverts element ").nth(1).and_then(|r| r.split(' ').next());
    let id: u64 = element.and_then(|e| e.parse().ok()).unwrap_or_else(|| panic!("{why}"));
    assert!(run.prepared.mesh.element_ids.contains(&id), "{why}");
    for part in ["the data's pull ([[measurement]] #1", " mm; the answer is the prior's"] {
        assert!(why.contains(part), "{part}: {why}");
    }
    assert!(!why.contains("refine"), "{why}");
    let largest = solved.solution.displacements.iter().map(|d| d.norm()).fold(0.0, f64::max);
    assert!(largest < 1e-9, "the prior of an unloaded box is rest: {largest} mm");
    assert!(solved.measurements.is_empty());
    let ctx = bs_scene::output::RunContext { total_seconds: 0.0, threads: 1 };
    let report = bs_scene::output::report(&run, &solved, ctx);
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["data_unused"].as_str(), Some(why.as_str()));
    let params = bs_scene::uncertainty::UncertaintyParams { samples: 8, ..Default::default() };
    let e = bs_scene::uncertainty::sample(&mut run, &solved, &params).unwrap_err().to_string();
    assert!(e.contains("--uncertainty: the measurements were not used (the data's pull"), "{e}");
    // In a session the data terms come back after the prior's answer: a reachable scan
    // (4 mm down) is then fitted as a cold run of it.
    let mut session = bs_scene::Session::new(Prepared::load(&path).unwrap()).unwrap();
    assert!(session.solve(&mut |_| {}).unwrap().data_unused.is_some());
    let reachable: Vec<Point3<f64>> = bs_mesh::io::points::read_points(&dir.join("scan.csv"))
        .unwrap()
        .iter()
        .map(|p| Point3::new(p.x, p.y, 36.0))
        .collect();
    let warm = session.update_points(&[("ZMAX".into(), reachable)], &mut |_| {}).unwrap();
    assert!(warm.data_unused.is_none() && warm.measurements.len() == 1);
    std::fs::write(dir.join("scan.csv"), plane_points(36.0)).unwrap();
    let cold = Run::prepare(Prepared::load(&path).unwrap()).unwrap().solve(&mut |_| {}).unwrap();
    let worst = (warm.solution.displacements.iter().zip(&cold.solution.displacements))
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "the session's scan against a cold run: {worst} mm");
}

/// Landmarks alone estimate gravity's level with the boundary: the held box under gravity,
/// its lower half buoyed by a fluid standing at z = 15, its top translated (a field in the
/// fit's basis); the scene believes the level at z = 25. Fitted through the top with the
/// level estimated, the answer is the truth's at every node and the level is found; fitted
/// without the estimate, the boundary alone cannot explain the deep landmarks (the test
/// fails if the level is not fitted).
#[test]
fn landmarks_alone_estimate_the_level_with_the_boundary() {
    let dir = tmp("landmarks-level");
    let gravity = |level: f64, estimate: &str| {
        format!(
            "[gravity]\ndirection = [0.0, 0.0, -1.0]\nacceleration = 9.81\n\
             fluid = {{ density = 1007.0, level = [20.0, 20.0, {level:?}] }}\n{estimate}\n"
        )
    };
    let dense = |path: PathBuf| {
        let text = std::fs::read_to_string(&path)
            .unwrap()
            .replace("poisson_ratio = 0.45 }", "poisson_ratio = 0.45, density = 1040.0 }");
        std::fs::write(&path, text).unwrap();
        path
    };
    let push = "[[boundary]]\nnset = \"ZMAX\"\ndisplacement = [0.5, 0.0, -1.0]\n";
    let truth = dense(held_box(&dir, &format!("{push}{}", gravity(15.0, ""))));
    let mut run = Run::prepare(Prepared::load(&truth).unwrap()).unwrap();
    let u_truth = run.solve(&mut |_| {}).unwrap().solution.displacements;
    let mesh = run.prepared.mesh.clone();
    std::fs::write(dir.join("pairs.csv"), landmark_pairs(&mesh, &u_truth, None)).unwrap();
    let fit = |estimate: &str| {
        let m = "[[measurement]]\nlandmarks = \"pairs.csv\"\nnset = \"ZMAX\"\nsigma = 0.005\n";
        let path = dense(held_box(&dir, &format!("{m}{}", gravity(25.0, estimate))));
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        let solved = run.solve(&mut |_| {}).unwrap();
        let worst = largest_difference(&solved.solution.displacements, &u_truth);
        (worst, solved.gravity.expect("the report's gravity"))
    };
    let (without, _) = fit("");
    let (with, g) = fit("estimate = { level = 15.0 }");
    let e = &g.estimates[0];
    assert_eq!(e.name, "level");
    assert_eq!(g.landmark_inliers, 12, "{g:?}");
    assert!(e.determined && e.standard_error > 0.0, "{e:?}");
    // The level 10 mm deeper along gravity; half a millimetre is 5 % of the offset.
    assert!((e.estimate - 10.0).abs() < 0.5, "{e:?}");
    assert!(with < 0.03, "largest error {with} mm with the level estimated");
    assert!(without > 3.0 * with, "without the estimate {without} mm, with {with} mm");
}
