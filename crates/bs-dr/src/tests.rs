//! Unit tests of the precomputation and the element tangent.

use bs_material::Material;
use bs_mesh::{Element, Mesh, Point3, Vector3};

use crate::model::{Model, ModelOptions, Solid};
use crate::newton::ElemView;

fn distorted_mesh() -> Mesh {
    // One distorted hex (bottom 0-1-2-3, top 4-5-6-7) and two tets sharing nodes with it.
    let nodes = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.1, 0.1, 0.0),
        Point3::new(1.0, 0.9, 0.1),
        Point3::new(-0.1, 1.0, 0.0),
        Point3::new(0.1, 0.0, 1.0),
        Point3::new(1.0, -0.1, 1.2),
        Point3::new(1.2, 1.1, 0.9),
        Point3::new(0.0, 1.0, 1.0),
        Point3::new(0.5, 0.5, 2.0),
    ];
    Mesh::new(
        nodes,
        vec![
            Element::hex8([0, 1, 2, 3, 4, 5, 6, 7]),
            Element::tet4([4, 5, 7, 8]),
            Element::tet4([5, 6, 7, 8]),
        ],
    )
}

fn model() -> Model {
    let solid = Solid { material: Material::neo_hookean(3000.0, 0.4).unwrap(), density: 1000.0 };
    Model::uniform(&distorted_mesh(), solid, ModelOptions::default()).unwrap()
}

/// Σ_a g_a = 0 and Σ_a X_a ⊗ g_a = I (exact reproduction of constant and linear fields), to
/// round-off relative to the unit entries.
#[test]
fn gradients_reproduce_linear_fields() {
    let m = model();
    let check = |nodes: &[u32], g: &[[f64; 3]]| {
        for k in 0..3 {
            let s: f64 = g.iter().map(|r| r[k]).sum();
            assert!(s.abs() < 1e-12);
            for l in 0..3 {
                let xg: f64 =
                    nodes.iter().zip(g).map(|(&n, r)| m.reference[n as usize][k] * r[l]).sum();
                assert!((xg - if k == l { 1.0 } else { 0.0 }).abs() < 1e-12, "{xg}");
            }
        }
    };
    for t in &m.tets {
        check(&t.nodes, &t.g);
    }
    for h in &m.hexes {
        check(&h.nodes, &h.g);
        // Mean-gradient volume equals the exact trilinear volume from bs-mesh.
        assert!((h.vol - distorted_mesh().element_volume(0)).abs() < 1e-12);
    }
}

/// The hourglass matrix annihilates every linear field `u = A X + c` and is not zero.
#[test]
fn hourglass_matrix_annihilates_linear_fields() {
    let m = model();
    let h = &m.hexes[0];
    let a = nalgebra::Matrix3::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.05, -0.3);
    let c = Vector3::new(0.4, -1.0, 2.0);
    let u: Vec<Vector3<f64>> =
        h.nodes.iter().map(|&n| a * m.reference[n as usize].coords + c).collect();
    let mut norm = 0.0f64;
    for r in 0..8 {
        let f: Vector3<f64> = (0..8).map(|s| u[s] * h.hg[r][s]).sum();
        assert!(f.amax() < 1e-9 * h.hg[r][r].abs().max(1.0), "{f}");
        norm = norm.max(h.hg[r][r].abs());
    }
    assert!(norm > 0.0);
    // Symmetric.
    for r in 0..8 {
        for s in 0..8 {
            assert!((h.hg[r][s] - h.hg[s][r]).abs() <= 1e-12 * norm);
        }
    }
}

/// The Newton element tangent equals the central finite difference of the kernel forces
/// (h = 1e-7 on displacements of O(0.1): truncation ~1e-14, round-off ~1e-16·f/1e-7 ~ 1e-9
/// relative; tolerance 1e-6 of the largest entry).
#[test]
fn element_tangent_matches_finite_difference_of_forces() {
    let m = model();
    let n = m.node_count();
    let u: Vec<Vector3<f64>> = (0..n)
        .map(|i| {
            Vector3::new(
                0.05 * (i as f64).sin(),
                0.04 * (1.3 * i as f64).cos(),
                -0.03 * (0.7 * i as f64).sin(),
            )
        })
        .collect();
    let views: Vec<ElemView<'_>> = m.elem_views().collect();
    let mut ws = m.workspace();
    let mut fp = vec![Vector3::zeros(); n];
    let mut fm = fp.clone();
    // Global K·v from element tangents vs FD of global forces.
    for probe in 0..3 * n {
        let (node, comp) = (probe / 3, probe % 3);
        let mut kv = vec![Vector3::<f64>::zeros(); n];
        let mut ke = vec![0.0; 24 * 24];
        for e in &views {
            let nn = e.nodes.len();
            let n3 = 3 * nn;
            assert!(m.element_tangent(e, &u, &mut ke[..n3 * n3]));
            if let Some(b) = e.nodes.iter().position(|&x| x as usize == node) {
                for a in 0..nn {
                    for i in 0..3 {
                        kv[e.nodes[a] as usize][i] += ke[(3 * a + i) * n3 + 3 * b + comp];
                    }
                }
            }
        }
        let h = 1e-7;
        let mut up = u.clone();
        up[node][comp] += h;
        let mut um = u.clone();
        um[node][comp] -= h;
        m.internal_forces_into(&up, &mut ws, &mut fp).unwrap();
        m.internal_forces_into(&um, &mut ws, &mut fm).unwrap();
        let scale = kv.iter().fold(0.0f64, |s, v| s.max(v.amax()));
        for a in 0..n {
            let fd = (fp[a] - fm[a]) / (2.0 * h);
            assert!((fd - kv[a]).amax() <= 1e-6 * scale, "dof {probe} node {a}: {fd} vs {}", kv[a]);
        }
    }
}

/// The 3-4-5 ramp: 0 and 1 at the ends, ½ in the middle, zero slope at both ends.
#[test]
fn ramp_345() {
    use crate::loads::ramp;
    assert_eq!(ramp(0.0), 0.0);
    assert_eq!(ramp(1.0), 1.0);
    assert_eq!(ramp(0.5), 0.5);
    assert_eq!(ramp(-1.0), 0.0);
    assert_eq!(ramp(2.0), 1.0);
    let h = 1e-6;
    assert!((ramp(h) - ramp(0.0)) / h < 1e-10);
    assert!((ramp(1.0) - ramp(1.0 - h)) / h < 1e-10);
    // d(τ) = 10τ³ − 15τ⁴ + 6τ⁵ at τ = 0.3.
    assert!((ramp(0.3) - (0.27 - 15.0 * 0.0081 + 6.0 * 0.00243)).abs() < 1e-15);
}

#[test]
fn load_errors_are_typed() {
    use crate::loads::{LoadError, Loads};
    let mut l = Loads::new(3);
    assert_eq!(l.fix(3, 0), Err(LoadError::NodeOutOfRange { node: 3, count: 3 }));
    assert_eq!(l.fix(0, 3), Err(LoadError::ComponentOutOfRange(3)));
    assert!(matches!(
        l.prescribe(1, 1, f64::NAN),
        Err(LoadError::NonFinite { node: 1, component: 1, .. })
    ));
    l.prescribe(2, 1, -0.5).unwrap();
    assert_eq!((l.max_prescribed(), l.constrained_count()), (0.5, 1));
}

/// Physical critical time step of a unit right tet (lumped mass ρV/4 per node) checked
/// against an independent dense eigen-solve of M⁻¹K for the 12×12 small-strain stiffness
/// assembled here from B and D.
#[test]
fn critical_time_step_of_a_tet_matches_dense_eigenvalue() {
    let nodes = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.0, 0.0, 1.0),
    ];
    let mesh = Mesh::new(nodes, vec![Element::tet4([0, 1, 2, 3])]);
    let material = Material::neo_hookean(3000.0, 0.3).unwrap();
    let m = Model::uniform(&mesh, Solid { material, density: 1000.0 }, ModelOptions::default())
        .unwrap();
    let (dt, e) = m.critical_time_step();
    assert_eq!(e, 0);
    // Dense K = V Bᵀ D B with gradients of the unit tet.
    let g = [[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let d = material.elastic().small_strain_tangent();
    let mut b = nalgebra::SMatrix::<f64, 6, 12>::zeros();
    for a in 0..4 {
        let [x, y, z] = g[a];
        let c = 3 * a;
        b[(0, c)] = x;
        b[(1, c + 1)] = y;
        b[(2, c + 2)] = z;
        b[(3, c + 1)] = z;
        b[(3, c + 2)] = y;
        b[(4, c)] = z;
        b[(4, c + 2)] = x;
        b[(5, c)] = y;
        b[(5, c + 1)] = x;
    }
    let vol = 1.0 / 6.0;
    let k = b.transpose() * d * b * vol;
    let lmax = nalgebra::SymmetricEigen::new(k).eigenvalues.max();
    let omega = (lmax / (1000.0 * vol / 4.0)).sqrt();
    assert!((dt - 2.0 / omega).abs() <= 1e-10 * dt, "{dt} vs {}", 2.0 / omega);
}
