//! Point clouds written by real tools (fixtures/readers/make.py: meshio's PLY, legacy VTK and
//! OBJ, and a VTK XML PolyData file) read to the points of the CSV they were written from.

use std::path::PathBuf;

use bs_mesh::io::points::read_points;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/readers").join(name)
}

#[test]
fn every_point_cloud_format_reads_to_the_csv_points() {
    let truth = read_points(&fixture("cloud.csv")).unwrap();
    assert_eq!(truth.len(), 50);
    for (name, tol) in [
        ("cloud.ply", 0.0),
        ("cloud-ascii.ply", 0.0),
        ("cloud.vtk", 0.0),
        ("cloud.vtp", 0.0),
        // meshio writes OBJ coordinates with numpy's default text format.
        ("cloud.obj", 1e-12),
    ] {
        let p = read_points(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(p.len(), truth.len(), "{name}");
        for (a, b) in p.iter().zip(&truth) {
            let d = (a - b).norm();
            assert!(d <= tol * (1.0 + b.coords.norm()), "{name}: {a} vs {b}");
        }
    }
}

#[test]
fn an_unknown_extension_or_a_missing_file_is_a_clear_error() {
    let e = read_points(&fixture("cloud.xyz")).unwrap_err().to_string();
    assert!(e.contains("cloud.xyz"), "{e}");
    let e = read_points(&fixture("cloud.txt")).unwrap_err().to_string();
    assert!(e.contains(".csv, .ply"), "{e}");
}
