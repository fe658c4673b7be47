//! `brainshift inspect` on one file of every supported format, and on bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/basic").join(name)
}

fn brainshift(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_brainshift")).args(args).output().expect("run brainshift")
}

fn inspect_json(path: &Path) -> Value {
    let out = brainshift(&["inspect", "--json", path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "inspect {} failed: {}\n{}",
        path.display(),
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    serde_json::from_slice(&out.stdout).expect("inspect --json prints JSON")
}

/// A temporary file that is removed on drop.
struct TempFile(PathBuf);

impl TempFile {
    fn new(name: &str, content: &[u8]) -> TempFile {
        let dir = std::env::temp_dir().join(format!("bs-cli-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, content).unwrap();
        TempFile(p)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

#[test]
fn the_same_cube_reads_alike_from_gmsh_msh41_msh22_and_its_inp_export() {
    for kind in ["t4", "h8"] {
        let reports: Vec<Value> = ["msh", "inp"]
            .iter()
            .map(|ext| format!("cube-{kind}.{ext}"))
            .chain([format!("cube-{kind}-v22.msh")])
            .map(|f| inspect_json(&fixture(&f)))
            .collect();
        for r in &reports {
            assert_eq!(r["nodes"], reports[0]["nodes"]);
            assert_eq!(r["elements"], reports[0]["elements"]);
            // Unit cube: the bounding box is exactly [0,1]^3 and the boundary encloses 1.
            assert_eq!(r["bounding_box"], serde_json::json!([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]));
            let s = &r["surface"];
            assert_eq!(
                (s["closed"].as_bool(), s["orientation"].as_str()),
                (Some(true), Some("outward"))
            );
            assert_eq!(s["euler_characteristic"], 2);
            let vol = s["enclosed_volume"].as_f64().unwrap();
            assert!((vol - 1.0).abs() < 1e-12, "{vol}");
            assert_eq!(r["valid"], true);
            assert_eq!(r["quality"]["inverted"], 0);
        }
    }
    // The structured hex cube: 3x3x3 cells, 4^3 nodes, every hex a perfect cube.
    let h8 = inspect_json(&fixture("cube-h8.msh"));
    assert_eq!((h8["nodes"].as_u64(), h8["elements"]["hex8"].as_u64()), (Some(64), Some(27)));
    let sj = &h8["quality"]["hex_scaled_jacobian"];
    assert!((sj["min"].as_f64().unwrap() - 1.0).abs() < 1e-12);
}

#[test]
fn the_ball_reads_alike_from_gmsh_msh_and_meshio_vtu_and_vtk() {
    let reports: Vec<Value> = ["sphere.msh", "sphere.vtu", "sphere.vtk"]
        .iter()
        .map(|f| inspect_json(&fixture(f)))
        .collect();
    for r in &reports {
        assert_eq!(r["elements"]["tet4"], reports[0]["elements"]["tet4"]);
        assert_eq!(r["bounding_box"], reports[0]["bounding_box"]);
        let s = &r["surface"];
        assert_eq!(s["closed"], true);
        assert_eq!(s["euler_characteristic"], 2);
        // A tetrahedral ball of radius 10 with mesh size 3 loses a few percent of volume
        // to its flat boundary facets (inscribed polyhedron): within 5% of 4/3 pi r^3.
        let v = s["enclosed_volume"].as_f64().unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
        assert!(v < exact && v > 0.95 * exact, "{v} vs {exact}");
    }
    // meshio writes only the points the cells use; gmsh's file has the same nodes.
    assert_eq!(reports[1]["nodes"], reports[2]["nodes"]);
}

#[test]
fn the_shell_surface_reads_alike_from_stl_obj_and_off() {
    let files = ["shell.stl", "shell-ascii.stl", "shell-gmsh.stl", "shell.obj", "shell.off"];
    let reports: Vec<Value> = files.iter().map(|f| inspect_json(&fixture(f))).collect();
    for (f, r) in files.iter().zip(&reports) {
        assert_eq!(r["kind"], "surface", "{f}");
        assert_eq!(r["nodes"], reports[0]["nodes"], "{f}: duplicate vertices must be merged");
        assert_eq!(r["elements"]["triangles"], reports[0]["elements"]["triangles"], "{f}");
        let s = &r["surface"];
        assert_eq!(
            (s["closed"].as_bool(), s["manifold"].as_bool()),
            (Some(true), Some(true)),
            "{f}"
        );
        assert_eq!(s["euler_characteristic"], 2, "{f}");
        let v = s["enclosed_volume"].as_f64().unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 12f64.powi(3);
        assert!(v.abs() < exact && v.abs() > 0.9 * exact, "{f}: {v}");
    }
}

#[test]
fn text_output_names_counts_and_status() {
    let out = brainshift(&["inspect", fixture("cube-h8.inp").to_str().unwrap()]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(out.status.success(), "{text}");
    assert!(text.contains("nodes:          64"), "{text}");
    assert!(text.contains("hex8: 27"), "{text}");
    assert!(text.contains("status: OK"), "{text}");
}

#[test]
fn an_inverted_element_makes_inspect_fail_naming_the_element() {
    let deck = b"*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 0, 1, 0\n4, 0, 0, 1\n\
                 *ELEMENT, TYPE=C3D4, ELSET=BRAIN\n7, 1, 3, 2, 4\n";
    let f = TempFile::new("inverted.inp", deck);
    let out = brainshift(&["inspect", f.0.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("element 7 (index 0) is inverted"), "{text}");
}

#[test]
fn malformed_and_unknown_files_are_clear_errors() {
    let f = TempFile::new("bad.inp", b"*NODE\n1, 0, 0, zero\n");
    let out = brainshift(&["inspect", f.0.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(err.contains("bad.inp:2:"), "error must name file and line: {err}");

    let out = brainshift(&["inspect", "no/such/file.msh"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/file.msh"));

    let out = brainshift(&["inspect", "mesh.xyz"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown file extension"));
}

#[test]
fn an_open_surface_is_reported_invalid() {
    // One triangle is not a closed surface.
    let f = TempFile::new("open.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    let out = brainshift(&["inspect", "--json", f.0.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let r: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["surface"]["closed"], false);
    assert_eq!(r["valid"], false);
}

#[test]
fn two_overlapping_shells_are_reported_as_self_intersecting() {
    // Two octahedra (circumradius 1) half a radius apart, written as one OFF surface: each
    // shell is closed, manifold and outward, but they cross.
    let verts = |dx: f64| {
        [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ]
        .map(|p| format!("{} {} {}\n", p[0] + dx, p[1], p[2]))
        .concat()
    };
    let faces = |o: usize| {
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
            .map(|t| format!("3 {} {} {}\n", t[0] + o, t[1] + o, t[2] + o))
            .concat()
    };
    let one = format!("OFF\n6 8 0\n{}{}", verts(0.0), faces(0));
    let f = TempFile::new("one.off", one.as_bytes());
    let r = inspect_json(&f.0);
    assert_eq!(r["valid"], true, "{r}");
    assert_eq!(r["surface"]["self_intersections"], 0);
    let two = format!("OFF\n12 16 0\n{}{}{}{}", verts(0.0), verts(0.5), faces(0), faces(6));
    let f = TempFile::new("two.off", two.as_bytes());
    let out = brainshift(&["inspect", "--json", f.0.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let r: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["surface"]["closed"], true);
    assert!(r["surface"]["self_intersections"].as_u64().unwrap() > 0, "{r}");
    let problems = r["problems"].to_string();
    assert!(problems.contains("intersects itself") && problems.contains("remesh"), "{problems}");
    let out = brainshift(&["inspect", f.0.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("SELF-INTERSECTING"));
}
