//! Loads from intra-operative data in `[[boundary]]`: an intra-operative surface (closest
//! points), landmark pairs (thin-plate spline) and craniotomy selections without a node set
//! (sphere, mask), checked against closed forms through `Prepared::load`, the path `check`
//! and `run` share.

use std::path::{Path, PathBuf};

use bs_mesh::{Mesh, Point3, TriSurface, Vector3};
use bs_scene::{Prepared, SceneError};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-loads-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 40 mm Kuhn box (5³ nodes) written as box.inp, and a scene with `boundaries` appended.
fn scene(dir: &Path, boundaries: &str) -> (PathBuf, Mesh) {
    let mesh = bs_mesh::structured::box_mesh(4, 40.0, true);
    bs_mesh::io::write_mesh(&dir.join("box.inp"), &mesh, &Default::default()).unwrap();
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"box.inp\"\n[[region]]\nelset = \"*\"\n\
         material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.45 }}\n\
         {boundaries}"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let mesh = bs_mesh::io::read_mesh(&dir.join("box.inp")).unwrap();
    (path, mesh)
}

/// The boundary nodes of `mesh` within `r` of `c` (the sphere selection, independently).
fn in_sphere(mesh: &Mesh, c: Point3<f64>, r: f64) -> Vec<usize> {
    (0..mesh.nodes.len())
        .filter(|&n| {
            let p = mesh.nodes[n];
            let on_boundary = p.iter().any(|&x| x == 0.0 || x == 40.0);
            on_boundary && (p - c).norm() <= r
        })
        .collect()
}

/// A plane patch through `p0` with normal `n`, 2 triangles per 10 mm cell, covering
/// x, y ∈ [−20, 60].
fn plane(p0: Point3<f64>, n: Vector3<f64>) -> TriSurface {
    let mut vertices = Vec::new();
    for j in 0..9 {
        for i in 0..9 {
            let (x, y) = (-20.0 + 10.0 * i as f64, -20.0 + 10.0 * j as f64);
            // z on the plane: n · (p − p0) = 0.
            let z = p0.z - (n.x * (x - p0.x) + n.y * (y - p0.y)) / n.z;
            vertices.push(Point3::new(x, y, z));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..8 {
        for i in 0..8 {
            let v = j * 9 + i;
            triangles.push([v, v + 1, v + 10]);
            triangles.push([v, v + 10, v + 9]);
        }
    }
    TriSurface { vertices, triangles }
}

#[test]
fn an_intra_operative_surface_moves_the_selected_nodes_to_their_closest_points() {
    let d = tmp("surface");
    // The top of the brain displaced by a known field: the plane z = 37 + 0.1 (x − 20)
    // (3 mm down at the centre, tilted). The closest point of a node p on a plane is
    // p − (n·(p − p0)) n: that is the expected displacement.
    let p0 = Point3::new(20.0, 20.0, 37.0);
    let n = Vector3::new(-0.1, 0.0, 1.0).normalize();
    bs_mesh::io::write_surface(&d.join("intraop.off"), &plane(p0, n)).unwrap();
    let (path, mesh) = scene(
        &d,
        "[[boundary]]\nsphere = { centre = [20.0, 20.0, 40.0], radius = 15.0 }\n\
         surface = \"intraop.off\"\n\
         [[boundary]]\nsphere = { centre = [20.0, 20.0, 0.0], radius = 12.0 }\nfix = [\"x\", \"y\", \"z\"]\n",
    );
    let p = Prepared::load(&path).unwrap();
    let selected = in_sphere(&mesh, Point3::new(20.0, 20.0, 40.0), 15.0);
    assert_eq!(selected.len(), 9, "the 3×3 top nodes within 15 mm of the top centre");
    // What `check` prints about it.
    assert!(
        p.loads.iter().any(|l| l.contains("intraop.off") && l.contains("9 nodes moved")),
        "{:?}",
        p.loads
    );
    for (node, pr) in p.prescribed.iter().enumerate() {
        if selected.contains(&node) {
            let x = mesh.nodes[node];
            let expect = -(n.dot(&(x - p0))) * n;
            for c in 0..3 {
                // Exact projection on a plane: rounding only.
                assert!((pr[c].unwrap() - expect[c]).abs() < 1e-12, "node {node}: {pr:?}");
            }
        } else if mesh.nodes[node].z == 0.0
            && (mesh.nodes[node] - Point3::new(20.0, 20.0, 0.0)).norm() <= 12.0
        {
            assert_eq!(*pr, [Some(0.0); 3]);
        } else {
            assert_eq!(*pr, [None; 3], "node {node} is not selected");
        }
    }
    // Too far: max_distance below the 3 mm gap lists the nodes, nearest-first not required.
    let (path, _) = scene(
        &d,
        "[[boundary]]\nsphere = { centre = [20.0, 20.0, 40.0], radius = 15.0 }\n\
         surface = \"intraop.off\"\nmax_distance = 1.0\n",
    );
    let e = Prepared::load(&path).unwrap_err().to_string();
    assert!(e.contains("9 of 9 selected nodes are farther than max_distance = 1"), "{e}");
    assert!(e.contains("node "), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn landmarks_reproduce_an_affine_displacement_exactly() {
    let d = tmp("landmarks");
    let a = nalgebra::Matrix3::new(1.02, 0.01, -0.03, 0.0, 0.97, 0.02, 0.01, -0.02, 1.04);
    let b = Vector3::new(0.5, -1.0, -2.5);
    let mut csv = String::from("x,y,z,x2,y2,z2\n");
    let mut rng = bs_mesh::rng::SplitMix64::new(5);
    for _ in 0..12 {
        let p = Vector3::new(rng.range(-5.0, 45.0), rng.range(-5.0, 45.0), rng.range(-5.0, 45.0));
        let q = a * p + b;
        csv += &format!("{},{},{},{},{},{}\n", p.x, p.y, p.z, q.x, q.y, q.z);
    }
    std::fs::write(d.join("pairs.csv"), &csv).unwrap();
    let (path, mesh) = scene(
        &d,
        "[[boundary]]\nsphere = { centre = [20.0, 20.0, 40.0], radius = 25.0 }\n\
         landmarks = \"pairs.csv\"\n",
    );
    let p = Prepared::load(&path).unwrap();
    let selected = in_sphere(&mesh, Point3::new(20.0, 20.0, 40.0), 25.0);
    assert!(selected.len() > 20);
    for &node in &selected {
        let x = mesh.nodes[node].coords;
        let expect = a * x + b - x;
        for c in 0..3 {
            // The spline reproduces affine maps exactly: LU rounding on a 16 × 16 system.
            assert!((p.prescribed[node][c].unwrap() - expect[c]).abs() < 1e-9, "node {node}");
        }
    }

    // Bad landmark files name the line.
    let cases = [
        (csv.replacen("\n", "\nnan,1,2,3,4,5\n", 1), "line 2: a coordinate is not finite"),
        (format!("{csv}{}", csv.lines().nth(1).unwrap()), "repeats line 2"),
        (csv.replace("x,y,z,x2,y2,z2", "a,b,c"), "the header must be x,y,z,x2,y2,z2"),
        (csv.replacen("\n", "\n1,2,3\n", 1), "line 2: expected 6 numbers"),
    ];
    for (bad, expect) in cases {
        std::fs::write(d.join("pairs.csv"), bad).unwrap();
        let e = Prepared::load(&path).unwrap_err().to_string();
        assert!(e.contains(expect) && e.contains("pairs.csv"), "{expect}: {e}");
    }
    // Nodes far outside the landmarks' bounding box: listed.
    let few = "x,y,z,x2,y2,z2\n0,0,0,0,0,1\n10,0,0,10,0,1\n0,10,0,0,10,1\n0,0,10,0,0,11\n";
    std::fs::write(d.join("pairs.csv"), few).unwrap();
    let e = Prepared::load(&path).unwrap_err().to_string();
    assert!(e.contains("outside the landmarks' bounding box") && e.contains("node "), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_mask_selects_the_boundary_nodes_on_its_non_zero_voxels() {
    let d = tmp("mask");
    // A 2 mm labelmap over the box: non-zero where z ≥ 35 and x ≤ 25.
    let grid =
        bs_image::Grid::axis_aligned([26, 26, 26], [2.0, 2.0, 2.0], [-5.0, -5.0, -5.0]).unwrap();
    let data = (0..grid.len())
        .map(|n| {
            let p = grid.world([(n % 26) as f64, ((n / 26) % 26) as f64, (n / 676) as f64]);
            u32::from(p.z >= 35.0 && p.x <= 25.0)
        })
        .collect();
    let mask = bs_image::Volume { grid, data };
    bs_image::nifti::write_labels(&d.join("craniotomy.nii.gz"), &mask, None).unwrap();
    let (path, mesh) =
        scene(&d, "[[boundary]]\nmask = \"craniotomy.nii.gz\"\ndisplacement = { z = -2.0 }\n");
    let p = Prepared::load(&path).unwrap();
    // Nodes at z = 40 (the top face; z = 30 is below 35) with x ∈ {0, 10, 20}: 3 × 5.
    let moved: Vec<usize> =
        (0..mesh.nodes.len()).filter(|&n| p.prescribed[n][2].is_some()).collect();
    let expect: Vec<usize> = (0..mesh.nodes.len())
        .filter(|&n| mesh.nodes[n].z == 40.0 && mesh.nodes[n].x <= 20.0)
        .collect();
    assert_eq!(moved, expect);

    // A mask that selects nothing, and a sphere away from the brain: errors, not no-ops.
    let empty = bs_image::Volume { grid: mask.grid.clone(), data: vec![0; mask.data.len()] };
    bs_image::nifti::write_labels(&d.join("craniotomy.nii.gz"), &empty, None).unwrap();
    let e = Prepared::load(&path).unwrap_err();
    assert!(
        matches!(e, SceneError::Set { .. }) && e.to_string().contains("holds no boundary node"),
        "{e}"
    );
    let (path, _) = scene(
        &d,
        "[[boundary]]\nsphere = { centre = [200.0, 0.0, 0.0], radius = 5.0 }\ndisplacement = { z = -2.0 }\n",
    );
    let e = Prepared::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("sphere centre [200.0, 0.0, 0.0]") && e.contains("holds no boundary node"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn load_keys_are_checked_at_parse_time() {
    let base = "units = \"mm\"\n[mesh]\nfile = \"a.inp\"\n[[region]]\nelset = \"*\"\n\
                material = { model = \"svk\", shear_modulus = 1000.0, bulk_modulus = 50000.0 }\n";
    let cases = [
        (
            "[[boundary]]\nnset = \"A\"\nsurface = \"s.stl\"\nlandmarks = \"l.csv\"\n",
            "exactly one of",
        ),
        (
            "[[boundary]]\nnset = \"A\"\nsphere = { centre = [0.0, 0.0, 0.0], radius = 1.0 }\nfix = [\"x\"]\n",
            "exactly one of nset, sphere or mask",
        ),
        (
            "[[boundary]]\nnset = \"A\"\nfix = [\"x\"]\nmax_distance = 2.0\n",
            "max_distance goes with surface",
        ),
        (
            "[[boundary]]\nnset = \"A\"\nsurface = \"s.stl\"\nmax_distance = -2.0\n",
            "max_distance must be positive",
        ),
        (
            "[[boundary]]\nsphere = { centre = [0.0, 0.0, 0.0], radius = 0.0 }\nfix = [\"x\"]\n",
            "sphere.radius must be positive",
        ),
        ("space = \"RAI\"\n", "space \"RAI\" is not a frame brainshift knows: use \"RAS\""),
    ];
    for (extra, expect) in cases {
        let text = if extra.starts_with("space") {
            format!("{extra}{base}")
        } else {
            format!("{base}{extra}")
        };
        let e = bs_scene::Scene::parse(&text).unwrap_err();
        assert!(e.contains(expect), "{extra}: {e}");
    }
    let s = bs_scene::Scene::parse(&format!("space = \"LPS\"\n{base}")).unwrap();
    assert_eq!(s.space, bs_image::Space::Lps);
}
