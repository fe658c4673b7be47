//! `[gravity]` in scenes and sessions: the body force's load against an independent count
//! (the weight of the brain), a turned direction in a live session against a cold run of a
//! scene with that direction, and the bad inputs refused by name.
//!
//! The case: a 40 mm Kuhn box (4³ cells) of brain tissue held at its base. Solves stop
//! when the last Newton correction is below the scene's tolerance, 1e-6 mm, converging
//! superlinearly; two of them agree to 1e-5 mm (ten tolerances) or better.

use std::path::{Path, PathBuf};

use bs_mesh::Vector3;
use bs_scene::{Prepared, Run, SceneError, Session};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-gravity-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The box with its base as node set BASE, and a scene with `gravity` (a TOML table body,
/// or empty for none) and the region's `density` key (`""` for none), written to `dir`.
fn scene(dir: &Path, density: &str, gravity: &str) -> PathBuf {
    let mut mesh = bs_mesh::structured::box_mesh(4, 40.0, true);
    let base = (0..mesh.nodes.len()).filter(|&n| mesh.nodes[n].z == 0.0).collect();
    mesh.node_sets.insert("BASE".into(), base);
    bs_mesh::io::write_mesh(&dir.join("box.inp"), &mesh, &Default::default()).unwrap();
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"box.inp\"\nelement = \"t4\"\n[[region]]\nelset = \"*\"\n\
         material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.45{density} }}\n\
         [[boundary]]\nnset = \"BASE\"\nfix = [\"x\", \"y\", \"z\"]\n\
         {gravity}\n[solver]\ntolerance = 1e-6\n"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

const DENSITY: &str = ", density = 1040.0";

fn gravity(direction: [f64; 3]) -> String {
    format!("[gravity]\ndirection = {direction:?}\n")
}

fn solve(path: &Path) -> Vec<Vector3<f64>> {
    let mut run = Run::prepare(Prepared::load(path).unwrap()).unwrap();
    run.solve(&mut |_| {}).unwrap().solution.displacements
}

fn max_diff(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).amax()).fold(0.0, f64::max)
}

#[test]
fn the_nodal_loads_weigh_the_box_in_the_scenes_units() {
    let d = tmp("weight");
    let path = scene(&d, DENSITY, &gravity([0.0, -2.0, 0.0]));
    let run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
    // 64 000 mm³ = 6.4e-5 m³ of 1040 kg/m³ at 9.81 m/s²: 0.65293 N = 652 930 µN (Pa·mm²).
    let weight = 6.4e-5 * 1040.0 * 9.81 * 1e6;
    let total: Vector3<f64> = run.composed.loads.forces().iter().sum();
    assert!((total - Vector3::new(0.0, -weight, 0.0)).norm() < 1e-9 * weight, "{total}");
}

#[test]
fn gravity_turned_in_a_session_equals_a_cold_run_with_that_direction() {
    let d = tmp("turn");
    let mut session =
        Session::new(Prepared::load(&scene(&d, DENSITY, &gravity([0.0, 0.0, -1.0]))).unwrap())
            .unwrap();
    let settled = session.solve(&mut |_| {}).unwrap().solution.displacements;
    // Under its own weight the box settles (about 0.2 mm at the top, 3 kPa tissue).
    let top = settled.iter().map(|u| -u.z).fold(0.0, f64::max);
    assert!(top > 0.05, "{top}");
    // The head turned: gravity along -x, then half-way back.
    for direction in [[-1.0, 0.0, 0.0], [-1.0, 0.0, -1.0]] {
        let warm = session.update_gravity(direction, &mut |_| {}).unwrap().solution.displacements;
        let cold = solve(&scene(&tmp("cold"), DENSITY, &gravity(direction)));
        let sway = cold.iter().map(|u| u.x.abs()).fold(0.0, f64::max);
        assert!(sway > 0.5, "{direction:?}: the box sways {sway} mm");
        assert!(max_diff(&warm, &cold) < 1e-5, "{direction:?}: {}", max_diff(&warm, &cold));
    }
    assert_eq!(session.gravity_direction(), Some([-1.0, 0.0, -1.0]));
    // A zero direction is refused, and the session keeps its direction and state.
    let before = session.displacements().to_vec();
    let e = session.update_gravity([0.0; 3], &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("[gravity] direction") && e.contains("non-zero"), "{e}");
    assert_eq!(session.gravity_direction(), Some([-1.0, 0.0, -1.0]));
    assert_eq!(session.displacements(), &before[..]);
}

#[test]
fn a_held_box_without_gravity_or_loads_is_refused_naming_gravity() {
    let d = tmp("none");
    let mut text = std::fs::read_to_string(scene(&d, DENSITY, "")).unwrap();
    text = text.replace("[solver]", "[[boundary]]\nnset = \"BASE\"\nfix = [\"x\"]\n[solver]");
    std::fs::write(d.join("scene.toml"), text).unwrap();
    // Nothing moves without gravity: the scene itself is refused, naming the fix.
    let e = Prepared::load(&d.join("scene.toml")).unwrap_err().to_string();
    assert!(e.contains("nothing to compute") && e.contains("[gravity]"), "{e}");
}

/// The error of preparing (and composing) the scene with `density` and `gravity`.
fn refusal(name: &str, density: &str, gravity: &str) -> String {
    let d = tmp(name);
    let path = scene(&d, density, gravity);
    let e: SceneError = match Prepared::load(&path) {
        Err(e) => e,
        Ok(p) => Run::prepare(p).expect_err("refused at composition"),
    };
    e.to_string()
}

#[test]
fn bad_gravity_is_refused_by_name() {
    let e = refusal("zero", DENSITY, &gravity([0.0; 3]));
    assert!(e.contains("[gravity] direction") && e.contains("non-zero"), "{e}");
    let e = refusal("nodensity", "", &gravity([0.0, 0.0, -1.0]));
    assert!(e.contains("material.density") && e.contains("elset '*'"), "{e}");
    let e = refusal("negative", ", density = -5.0", &gravity([0.0, 0.0, -1.0]));
    assert!(e.contains("density must be positive"), "{e}");
    let g = "[gravity]\ndirection = [0.0, 0.0, -1.0]\nacceleration = -9.81\n";
    assert!(refusal("accel", DENSITY, g).contains("acceleration"));
    let fluid = |level: f64, density: f64| {
        format!(
            "[gravity]\ndirection = [0.0, 0.0, -1.0]\nfluid = {{ density = {density}, level = [20.0, 20.0, {level}] }}\n"
        )
    };
    // The box spans z in [0, 40]: a level at 55 drowns it, one at -3 leaves it dry.
    let e = refusal("above", DENSITY, &fluid(55.0, 1007.0));
    assert!(
        e.contains("15.0 mm above the brain's highest point") && e.contains("submerged"),
        "{e}"
    );
    let e = refusal("below", DENSITY, &fluid(-3.0, 1007.0));
    assert!(
        e.contains("3.0 mm below the brain's lowest point") && e.contains("Remove `fluid`"),
        "{e}"
    );
    let e = refusal("fluiddensity", DENSITY, &fluid(20.0, 0.0));
    assert!(e.contains("fluid.density"), "{e}");
    // A level through the brain is taken.
    let d = tmp("good");
    assert!(
        Run::prepare(Prepared::load(&scene(&d, DENSITY, &fluid(20.0, 1007.0))).unwrap()).is_ok()
    );
}
