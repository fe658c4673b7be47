//! The element layer on its own: elements built from the points of a distorted mixed mesh.

use bs_material::Material;
use bs_mesh::{ElementKind, Mesh, Vector3};

use super::{Hex, Tet};
use crate::tests::distorted_mesh;

/// The elements of [`distorted_mesh`]: the mesh, its tets and its hexes.
fn elements() -> (Mesh, Vec<Tet>, Vec<Hex>) {
    let mesh = distorted_mesh();
    let el = Material::neo_hookean(3000.0, 0.4).unwrap().elastic();
    let (mut tets, mut hexes) = (Vec::new(), Vec::new());
    for e in &mesh.elements {
        let n = e.nodes();
        match e.kind() {
            ElementKind::Tet4 => {
                let x = std::array::from_fn(|a| mesh.nodes[n[a]]);
                tets.push(Tet::new(std::array::from_fn(|a| n[a] as u32), 0, &x).unwrap());
            }
            ElementKind::Hex8 => {
                let x = std::array::from_fn(|a| mesh.nodes[n[a]]);
                let nodes = std::array::from_fn(|a| n[a] as u32);
                hexes.push(Hex::new(nodes, 0, &x, &el, 0.1).unwrap());
            }
        }
    }
    (mesh, tets, hexes)
}

/// Σ_a g_a = 0 and Σ_a X_a ⊗ g_a = I (exact reproduction of constant and linear fields), to
/// round-off relative to the unit entries.
#[test]
fn gradients_reproduce_linear_fields() {
    let (mesh, tets, hexes) = elements();
    let check = |nodes: &[u32], g: &[[f64; 3]]| {
        for k in 0..3 {
            let s: f64 = g.iter().map(|r| r[k]).sum();
            assert!(s.abs() < 1e-12);
            for l in 0..3 {
                let xg: f64 =
                    nodes.iter().zip(g).map(|(&n, r)| mesh.nodes[n as usize][k] * r[l]).sum();
                assert!((xg - if k == l { 1.0 } else { 0.0 }).abs() < 1e-12, "{xg}");
            }
        }
    };
    for t in &tets {
        check(&t.nodes, &t.g);
    }
    for h in &hexes {
        check(&h.nodes, &h.g);
        // Mean-gradient volume equals the exact trilinear volume from bs-mesh.
        assert!((h.vol - mesh.element_volume(0)).abs() < 1e-12);
    }
}

/// The hourglass matrix annihilates every linear field `u = A X + c` and is not zero.
#[test]
fn hourglass_matrix_annihilates_linear_fields() {
    let (mesh, _, hexes) = elements();
    let h = &hexes[0];
    let a = nalgebra::Matrix3::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.05, -0.3);
    let c = Vector3::new(0.4, -1.0, 2.0);
    let u: Vec<Vector3<f64>> =
        h.nodes.iter().map(|&n| a * mesh.nodes[n as usize].coords + c).collect();
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

/// A tet with its apex pushed through the base is refused with its negative volume; a hex
/// with top and bottom swapped with its negative Jacobian.
#[test]
fn inverted_elements_are_refused_with_their_jacobian() {
    let (mesh, _, _) = elements();
    let x = [mesh.nodes[4], mesh.nodes[5], mesh.nodes[8], mesh.nodes[7]];
    let vol = Tet::new([4, 5, 8, 7], 0, &x).unwrap_err();
    assert!(vol < 0.0, "{vol}");
    let el = Material::neo_hookean(3000.0, 0.4).unwrap().elastic();
    let order = [4, 5, 6, 7, 0, 1, 2, 3];
    let x = std::array::from_fn(|a| mesh.nodes[order[a]]);
    let det = Hex::new(order.map(|n| n as u32), 0, &x, &el, 0.1).unwrap_err();
    assert!(det < 0.0, "{det}");
}
