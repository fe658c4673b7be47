//! End-to-end: `brainshift run` and `check` on the bundled scenes, the cube patch cases
//! against closed forms, and the bad-scene corpus.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

mod common;

use common::{TempDir, brainshift};

/// Runs a scene; returns report.json and the displacements by node id.
fn run_scene(scene: &Path, out: &Path) -> (Value, HashMap<u64, [f64; 3]>) {
    let o =
        brainshift(&["run", scene.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(
        o.status.success(),
        "run {} failed:\n{}\n{}",
        scene.display(),
        String::from_utf8_lossy(&o.stderr),
        String::from_utf8_lossy(&o.stdout)
    );
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let csv = std::fs::read_to_string(out.join("displacements.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("node_id,ux,uy,uz"));
    let u = lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v = |i: usize| f[i].parse::<f64>().unwrap();
            (f[0].parse::<u64>().unwrap(), [v(1), v(2), v(3)])
        })
        .collect();
    (report, u)
}

/// The bundled contact scenes converge, leave no node outside the skull and report contact;
/// the result files agree with each other.
fn assert_contact_scene(dir: &str, name: &str) {
    let scene = root().join("fixtures").join(dir).join("scene.toml");
    let out = TempDir::new_in("run", name);
    let (r, u) = run_scene(&scene, &out.0);
    assert_eq!(r["converged"], true);
    assert!(r["error_estimate"].as_f64().unwrap() < r["tolerance"].as_f64().unwrap());
    assert!(r["nodes_in_contact"].as_u64().unwrap() > 0, "{r}");
    assert!(r["max_penetration_before_correction"].as_f64().unwrap() > 0.0, "{r}");
    // After enforcement no slave is outside the skull by more than 1e-9 of the model size
    // (~100 mm): the kinematic correction puts nodes on the skull to rounding.
    assert!(r["max_penetration_after"].as_f64().unwrap() <= 1e-7, "{r}");

    let mesh =
        bs_mesh::io::read_mesh(&root().join("fixtures").join(dir).join("brain.inp")).unwrap();
    assert_eq!(u.len(), mesh.nodes.len());
    // Prescribed nodes end exactly at their prescribed values; fixed nodes do not move.
    for (set, expect) in [("FIXED", 0.0)] {
        for &n in mesh.node_set(set).unwrap() {
            assert_eq!(u[&mesh.node_ids[n]], [expect; 3], "{set} node {}", mesh.node_ids[n]);
        }
    }
    // result.vtu carries the same displacements (bitwise) and a contact flag per node.
    let (vmesh, fields) = match bs_mesh::io::read(&out.0.join("result.vtu")).unwrap() {
        bs_mesh::io::MeshFile::Volume(m, f) => (m, f),
        other => panic!("result.vtu is not a volume mesh: {other:?}"),
    };
    assert_eq!(vmesh.node_ids, mesh.node_ids);
    let disp = fields.point.iter().find(|f| f.name == "displacement").unwrap();
    for (i, id) in vmesh.node_ids.iter().enumerate() {
        assert_eq!(&disp.values[3 * i..3 * i + 3], &u[id][..]);
    }
    let flag = fields.point.iter().find(|f| f.name == "in_contact").unwrap();
    let flagged = flag.values.iter().filter(|&&v| v == 1.0).count() as u64;
    assert_eq!(flagged, r["nodes_in_contact"].as_u64().unwrap());
    let j = fields.cell.iter().find(|f| f.name == "J").unwrap();
    assert!(j.values.iter().all(|&j| j > 0.0 && j.is_finite()));
}

#[test]
fn sphere_in_shell_converges_with_contact_and_no_node_outside() {
    assert_contact_scene("sphere-shell", "sphere-shell");
}

#[test]
fn mni152_brain_converges_with_contact_and_no_node_outside() {
    assert_contact_scene("mni152", "mni152");
}

/// report.json read back typed (`RunReport::read`, as registration and sweeps read it)
/// holds every key it was written with, with the same values (the column's gravity
/// included).
#[test]
fn report_json_reads_back_typed_with_every_key() {
    for (k, scene) in
        ["fixtures/cube/uniaxial-t4.toml", "fixtures/column/scene.toml"].iter().enumerate()
    {
        let scene = root().join(scene);
        let dir = TempDir::new_in("run", &format!("typed-report-{k}"));
        let (written, _) = run_scene(&scene, &dir.0);
        let typed = bs_scene::output::RunReport::read(&dir.0.join("report.json")).unwrap();
        let back = serde_json::to_value(&typed).unwrap();
        for (key, value) in written.as_object().unwrap() {
            assert_eq!(&back[key], value, "{}: key {key}", scene.display());
        }
        assert!(typed.converged && typed.units == Some(bs_scene::scene::Units::Mm), "{typed:?}");
    }
}

/// `check --json` prints the report the library builds, field for field, and the text
/// names each region's material as the scene spells it.
#[test]
fn check_prints_the_librarys_report_as_json_and_as_text() {
    let scene = root().join("fixtures/mni152-regions/scene.toml");
    let o = brainshift(&["check", scene.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let printed: bs_scene::check::CheckReport =
        serde_json::from_slice(&o.stdout).expect("check --json prints a CheckReport");
    let mut expected = bs_scene::check::check(&scene).unwrap().report();
    expected.scene = printed.scene.clone(); // the path as given on each side
    expected.mesh = printed.mesh.clone();
    expected.skull.as_mut().unwrap().file = printed.skull.as_ref().unwrap().file.clone();
    // The same text (serde_json's parser may round a float's last bit, its printer not).
    let text = serde_json::to_string_pretty(&expected).unwrap();
    assert_eq!(String::from_utf8_lossy(&o.stdout).trim_end(), text);
    assert_eq!(printed.regions.len(), 3);
    assert_eq!(printed.regions[2].model, "svk");
    let o = brainshift(&["check", scene.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("region 'VENTRICLES': 70 elements, svk, mu = "), "{text}");
    assert!(text.contains("algorithm coherent"), "{text}");
}

#[test]
fn check_rejects_a_brain_that_pokes_through_the_skull() {
    let o =
        brainshift(&["check", root().join("fixtures/bad/skull-too-small.toml").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    // Names nodes by id with their distance outside.
    assert!(
        err.contains("brain surface nodes are outside the skull before any load: node "),
        "{err}"
    );
}

#[test]
fn bad_scenes_fail_with_their_expected_message() {
    let dir = root().join("fixtures/bad");
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 60, "the corpus must hold at least 60 scenes");
    for scene in scenes {
        let text = std::fs::read_to_string(&scene).unwrap();
        let expect = text
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("# expect: "))
            .unwrap_or_else(|| panic!("{} lacks its '# expect:' line", scene.display()));
        let o = brainshift(&["check", scene.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(
            o.status.code(),
            Some(1),
            "{}: expected a clean failure, got:\n{err}",
            scene.display()
        );
        assert!(err.contains(expect), "{}: expected '{expect}' in:\n{err}", scene.display());
        assert!(!err.contains("panicked"), "{}: {err}", scene.display());
    }
}

/// The command cases of the bad-input corpus (`fixtures/bad/commands.txt`: arguments, a tab,
/// the text stderr must contain): each exits 1 with its message, never panics and writes
/// nothing (neither in the corpus folder nor in the `{out}` folder it is given).
#[test]
fn bad_commands_fail_with_their_expected_message() {
    let dir = root().join("fixtures/bad");
    let listing = |d: &Path| {
        let mut v: Vec<_> = std::fs::read_dir(d).unwrap().map(|e| e.unwrap().path()).collect();
        v.sort();
        v
    };
    let before = listing(&dir);
    let table = std::fs::read_to_string(dir.join("commands.txt")).unwrap();
    let mut cases = 0;
    for line in table.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
        let (args, expect) =
            line.split_once('\t').unwrap_or_else(|| panic!("no tab in commands.txt line: {line}"));
        let out = TempDir::new_in("run", &format!("bad-command-{cases}"));
        let args: Vec<String> =
            args.split_whitespace().map(|a| a.replace("{out}", out.0.to_str().unwrap())).collect();
        let o = Command::new(env!("CARGO_BIN_EXE_brainshift"))
            .args(&args)
            .current_dir(&dir)
            .output()
            .expect("run brainshift");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: expected a clean failure, got:\n{err}");
        assert!(err.contains(expect), "{args:?}: expected '{expect}' in:\n{err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(listing(&out.0).is_empty(), "{args:?} wrote {:?}", listing(&out.0));
        cases += 1;
    }
    assert_eq!(listing(&dir), before, "a bad command wrote into fixtures/bad");
    assert!(cases >= 25, "commands.txt must hold at least 25 cases, has {cases}");
}

/// Zero is not a thread count: refused with a message, nothing written.
#[test]
fn zero_threads_are_refused() {
    let dir = TempDir::new_in("run", "zero-threads");
    let scene = root().join("fixtures/cube/uniaxial-t4.toml");
    let out = dir.0.join("out");
    let o = brainshift(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--threads",
        "0",
        "--quiet",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--threads 0: give at least 1 worker thread"), "{err}");
    assert!(!out.exists(), "nothing may be written");
}

/// A run interrupted by SIGINT (or SIGTERM) mid-solve stops between steps, says which step
/// and error it reached, exits 130 and writes nothing.
#[cfg(unix)]
#[test]
fn an_interrupted_run_writes_nothing_and_says_where_it_stopped() {
    use std::io::BufRead;
    use std::process::{Command, Stdio};
    for signal in ["INT", "TERM"] {
        let dir = TempDir::new_in("run", &format!("interrupted-{signal}"));
        // The MNI152 scene with Dynamic Relaxation: thousands of steps, many seconds.
        let fixture = root().join("fixtures/mni152");
        let text = std::fs::read_to_string(fixture.join("scene.toml"))
            .unwrap()
            .replace("\"brain.inp\"", &format!("{:?}", fixture.join("brain.inp")))
            .replace("\"skull.off\"", &format!("{:?}", fixture.join("skull.off")))
            .replace("kind = \"newton-krylov\"", "kind = \"dr\"");
        assert!(text.contains("kind = \"dr\""));
        let scene = dir.0.join("scene.toml");
        std::fs::write(&scene, text).unwrap();
        let out = dir.0.join("out");
        let mut child = Command::new(env!("CARGO_BIN_EXE_brainshift"))
            .args(["run", scene.to_str().unwrap(), "--out", out.to_str().unwrap()])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
        // Wait for the first progress line: the solve is under way.
        let mut seen = Vec::new();
        for line in lines.by_ref() {
            let line = line.unwrap();
            let started = line.trim_start().starts_with("step");
            seen.push(line);
            if started {
                break;
            }
        }
        assert!(seen.last().is_some_and(|l| l.trim_start().starts_with("step")), "{seen:?}");
        let pid = child.id().to_string();
        assert!(
            Command::new("kill").args([&format!("-{signal}"), &pid]).status().unwrap().success()
        );
        let rest: Vec<String> = lines.map(Result::unwrap).collect();
        let status = child.wait().unwrap();
        let err = rest.join("\n");
        assert_eq!(status.code(), Some(130), "SIG{signal}: {err}");
        assert!(err.contains("interrupted at step "), "SIG{signal}: {err}");
        assert!(err.contains("nothing written"), "SIG{signal}: {err}");
        let written: Vec<_> = std::fs::read_dir(&out)
            .map(|d| d.flatten().map(|e| e.path()).collect())
            .unwrap_or_default();
        assert!(written.is_empty(), "SIG{signal}: partial outputs {written:?}");
    }
}

/// The same scene gives byte-identical displacements for 1 and 2 threads and across
/// repeated runs (the force assembly gathers in a fixed order; no atomics in sums).
#[test]
fn displacements_are_identical_for_any_thread_count_and_every_run() {
    let dir = TempDir::new_in("run", "determinism");
    let scene = root().join("fixtures/sphere-shell/scene.toml");
    let mut files = Vec::new();
    for (k, threads) in ["1", "2", "2", "1"].iter().enumerate() {
        let out = dir.0.join(format!("run{k}"));
        let o = brainshift(&[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            threads,
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        files.push(std::fs::read(out.join("displacements.csv")).unwrap());
    }
    assert!(files[0].len() > 1000);
    for (k, f) in files.iter().enumerate().skip(1) {
        assert!(f == &files[0], "run {k} differs from run 0");
    }
}

fn cube_mesh(element: &str) -> bs_mesh::Mesh {
    let file = if element == "h8" { "cube-h8.msh" } else { "cube-t4.msh" };
    bs_mesh::io::read_mesh(&root().join("fixtures/basic").join(file)).unwrap()
}

/// Uniaxial compression of the unit cube with symmetry planes through the CLI
/// (fixtures/cube/uniaxial-*.toml): every node matches the homogeneous field
/// u = ((l−1)x, (l−1)y, (λ−1)z) to 1e-6 relative, for T4, T4ANP (unstructured gmsh tets)
/// and H8.
#[test]
fn cube_uniaxial_compression_matches_the_closed_form() {
    let (e, nu) = (3000.0, 0.3);
    let (mu, kappa) = (e / (2.0 * (1.0 + nu)), e / (3.0 * (1.0 - 2.0 * nu)));
    let lambda = 0.9;
    let l = bs_material::closed_form::neo_hookean_uniaxial_lateral_stretch(lambda, mu, kappa)
        .expect("bracketed");
    for element in ["t4", "t4anp", "h8"] {
        let scene = root().join(format!("fixtures/cube/uniaxial-{element}.toml"));
        let dir = TempDir::new_in("run", &format!("uniaxial-{element}"));
        let (_, u) = run_scene(&scene, &dir.0);
        let mesh = cube_mesh(element);
        let mut worst = 0.0f64;
        for (i, p) in mesh.nodes.iter().enumerate() {
            let exact = [(l - 1.0) * p.x, (l - 1.0) * p.y, (lambda - 1.0) * p.z];
            let got = u[&mesh.node_ids[i]];
            for c in 0..3 {
                worst = worst.max((got[c] - exact[c]).abs());
            }
        }
        // Relative to the largest displacement (0.1).
        assert!(worst <= 1e-6 * 0.1, "{element}: max error {worst:e}");
    }
}

/// Simple shear with every boundary node prescribed from a displacement file
/// (fixtures/cube/shear-*.toml): interior nodes follow u = (γ y, 0, 0) to 1e-6 relative —
/// a homogeneous deformation is the exact solution for any hyperelastic law.
#[test]
fn cube_simple_shear_matches_the_closed_form() {
    let gamma = 0.2;
    for element in ["t4", "t4anp", "h8"] {
        let scene = root().join(format!("fixtures/cube/shear-{element}.toml"));
        let dir = TempDir::new_in("run", &format!("shear-{element}"));
        let (_, u) = run_scene(&scene, &dir.0);
        let mesh = cube_mesh(element);
        let interior = mesh.nodes.len() - mesh.boundary().volume_node.len();
        assert!(interior > 0);
        let mut worst = 0.0f64;
        for (i, p) in mesh.nodes.iter().enumerate() {
            let got = u[&mesh.node_ids[i]];
            worst = worst.max((got[0] - gamma * p.y).abs()).max(got[1].abs()).max(got[2].abs());
        }
        assert!(worst <= 1e-6 * gamma, "{element}: max error {worst:e}");
    }
}

/// `--uncertainty N` on the fitted fixture: σ per node in uncertainty.csv (zero where the
/// brain stem is held, positive under the scan), the σ volume on a 1 mm RAS grid and
/// report.json's section agree; fewer than two samples are refused before anything runs.
#[test]
fn the_uncertainty_of_the_fitted_fixture_is_written_three_ways() {
    let dir = TempDir::new_in("run", "uncertainty");
    let out = dir.0.join("out");
    let scene = root().join("fixtures/fit/scene.toml");
    let (s, o) = (scene.to_str().unwrap(), out.to_str().unwrap());
    let refused = brainshift(&["run", s, "--out", o, "--uncertainty", "1", "--quiet"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("1 samples: give at least 2"), "{err}");
    assert!(!out.exists(), "nothing may be written");
    let loose = ["run", s, "--out", o, "--uncertainty", "8", "--uncertainty-tolerance", "1.5"];
    let refused = brainshift(&loose);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("relative residual between 0 and 1"), "{err}");
    assert!(!out.exists(), "nothing may be written");
    let ran = brainshift(&["run", s, "--out", o, "--uncertainty", "8", "--quiet"]);
    assert!(ran.status.success(), "{}", String::from_utf8_lossy(&ran.stderr));
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let u = &report["uncertainty"];
    assert_eq!(u["samples"], 8);
    assert_eq!(u["tolerance"], 1e-2, "the default relative residual, recorded");
    let csv = std::fs::read_to_string(out.join("uncertainty.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("node_id,sx,sy,sz,s"));
    let rows: HashMap<u64, [f64; 4]> = lines
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (f[0] as u64, [f[1], f[2], f[3], f[4]])
        })
        .collect();
    assert_eq!(rows.len() as u64, report["nodes"].as_u64().unwrap());
    let mesh = bs_mesh::io::read_mesh(&root().join("fixtures/mni152-regions/brain.inp")).unwrap();
    let id =
        |set: &str| -> Vec<u64> { mesh.node_sets[set].iter().map(|&n| mesh.node_ids[n]).collect() };
    assert!(id("FIXED").iter().all(|n| rows[n][3] == 0.0), "held nodes have no σ");
    let scanned = id("CRANIOTOMY");
    let mean = scanned.iter().map(|n| rows[n][3]).sum::<f64>() / scanned.len() as f64;
    // σ 1 mm per point, hundreds of points: the surface under them is known to tenths.
    assert!(mean > 0.01 && mean < 1.0, "{mean}");
    let max = rows.values().map(|r| r[3]).fold(0.0, f64::max);
    assert!((u["max_sigma"].as_f64().unwrap() - max).abs() < 1e-9 * (1.0 + max));
    for r in rows.values() {
        let total = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        assert!((total - r[3]).abs() < 1e-12 * (1.0 + total));
    }
    let nii = std::fs::metadata(out.join("uncertainty.nii.gz")).unwrap();
    assert!(nii.len() > 1000);
    // The preview of a warp of this result has σ as a fourth column (four 300-pixel panels
    // and two 110-pixel colour bars; three panels and one bar without σ, bs-preview).
    let (nii, png) = (out.join("uncertainty.nii.gz"), dir.0.join("preview.png"));
    let warped = dir.0.join("warped.nii.gz");
    let args = ["warp", "--image", nii.to_str().unwrap(), "--result", o];
    let w = brainshift(
        &[&args[..], &["--out", warped.to_str().unwrap(), "--preview", png.to_str().unwrap()]]
            .concat(),
    );
    assert!(w.status.success(), "{}", String::from_utf8_lossy(&w.stderr));
    let png = std::fs::read(&png).unwrap();
    let width = u32::from_be_bytes([png[16], png[17], png[18], png[19]]);
    assert_eq!(width, 4 * 300 + 2 * 110);
}
