//! The paper's first experiment by the paper's method: `fixtures/ellipsoid/scene-40mm-dr.toml`
//! (the hexahedral ellipsoid pushed 40 mm into its skull, Dynamic Relaxation with kinematic
//! contact) converges, and lands on Newton–Krylov's equilibrium of the same scene, stored as
//! every tenth node of its `displacements.csv` in
//! `fixtures/ellipsoid/reference/nk-hex-40mm.csv` (fixtures/ellipsoid/README.md says how it
//! was made). Both solvers stop at 1e-3 mm; measured 0.0004 mm mean, 0.0009 mm max apart.
//! The tolerances are the paper's own agreement with LS-Dyna (0.12 mm mean) and 1 mm max
//! (issue targets); a DR that stopped early or slid to another contact state would miss
//! them by millimetres.

use std::path::PathBuf;

use bs_scene::{Prepared, Run};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn dr_carries_the_papers_40_mm_push_of_the_hexahedral_ellipsoid() {
    let scene = root().join("fixtures/ellipsoid/scene-40mm-dr.toml");
    let p = Prepared::load(&scene).unwrap();
    assert_eq!(p.scene.solver.kind, bs_scene::scene::SolverKind::Dr);
    let mut run = Run::prepare(p).unwrap();
    let out = run.solve(&mut |_| {}).expect("DR converges at 40 mm");
    let u = &out.solution.displacements;
    let ids = run.prepared.mesh.node_ids.clone();
    let text = std::fs::read_to_string(root().join("fixtures/ellipsoid/reference/nk-hex-40mm.csv"))
        .unwrap();
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let node = ids.iter().position(|&id| id == v[0] as u64).expect("node id in the mesh");
        let d = (u[node] - bs_mesh::Vector3::new(v[1], v[2], v[3])).norm();
        sum += d;
        max = max.max(d);
        n += 1;
    }
    assert_eq!(n, 1415);
    let mean = sum / n as f64;
    assert!(mean <= 0.12 && max <= 1.0, "DR vs Newton-Krylov: mean {mean} mm, max {max} mm");
}
