//! The vectorised kernels against the scalar reference, and inverted elements.

use bs_material::Material;
use bs_mesh::rng::SplitMix64;
use bs_mesh::structured::jittered_box_mesh;
use bs_mesh::{Mesh, Vector3};

use crate::element::kinematics::{deformation_gradient, det3};
use crate::{Inversion, Model, ModelOptions, Solid, TetFormulation};

/// Unit box of `n³` cells, interior nodes jittered by up to 0.2 h per axis.
fn jittered_box(n: usize, tets: bool) -> Mesh {
    jittered_box_mesh(n, 1.0, tets, 0.2, 5)
}

/// A smooth large deformation (stretch, shear, compression; J from about 0.8 to 1.2) plus
/// a random perturbation.
fn deformation(mesh: &Mesh) -> Vec<Vector3<f64>> {
    let mut rng = SplitMix64::new(9);
    mesh.nodes
        .iter()
        .map(|p| {
            Vector3::new(
                0.08 * (3.0 * p.z).sin() + 0.1 * p.x * p.y,
                0.07 * p.x * p.z - 0.05 * p.y,
                -0.12 * p.z * p.z + 0.04 * (2.0 * p.x).sin(),
            ) + Vector3::new(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5) * 0.01
        })
        .collect()
}

/// With `mixed`, most elements are Neo-Hookean, some a second Neo-Hookean and some St
/// Venant–Kirchhoff: blocks with several laws take the per-element path.
fn model(mesh: &Mesh, tet: TetFormulation, mixed: bool) -> Model {
    let solids = [
        Solid { material: Material::neo_hookean(3000.0, 0.49).unwrap(), density: 1000.0 },
        Solid { material: Material::neo_hookean(5000.0, 0.45).unwrap(), density: 1000.0 },
        Solid { material: Material::st_venant_kirchhoff(3000.0, 0.4).unwrap(), density: 1000.0 },
    ];
    let assignment: Vec<usize> = (0..mesh.elements.len())
        .map(|e| match (mixed, e % 11, e % 5) {
            (true, 0, _) => 2,
            (true, _, 0) => 1,
            _ => 0,
        })
        .collect();
    Model::new(mesh, &solids, &assignment, ModelOptions { tet, ..Default::default() }).unwrap()
}

type Forces = Result<Vec<Vector3<f64>>, Inversion>;

/// Forces on the portable lanes: one worker thread with the override set, so that every
/// `dispatch` of this evaluation runs there.
fn portable(model: &Model, u: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| {
        super::simd::FORCE_PORTABLE.set(true);
        let mut f = vec![Vector3::zeros(); model.node_count()];
        model.internal_forces_into(u, &mut model.workspace(), &mut f).unwrap();
        super::simd::FORCE_PORTABLE.set(false);
        f
    })
}

fn both(model: &Model, u: &[Vector3<f64>]) -> (Forces, Forces) {
    let n = model.node_count();
    let mut f = vec![Vector3::zeros(); n];
    let new = model.internal_forces_into(u, &mut model.workspace(), &mut f).map(|_| f);
    let mut f = vec![Vector3::zeros(); n];
    let old =
        model.internal_forces_scalar_into(u, &mut model.reference_workspace(), &mut f).map(|_| f);
    (new, old)
}

const CASES: [(&str, bool, TetFormulation); 3] = [
    ("T4", true, TetFormulation::T4),
    ("T4ANP", true, TetFormulation::T4Anp),
    ("H8", false, TetFormulation::T4),
];

#[test]
fn simd_kernels_match_the_scalar_reference() {
    // 5³ cells: 750 tets, so the last block of four is padded.
    for (name, tets, tet) in CASES {
        let mesh = jittered_box(5, tets);
        let u = deformation(&mesh);
        for mixed in [false, true] {
            let m = model(&mesh, tet, mixed);
            let (new, old) = both(&m, &u);
            let (new, old) = (new.unwrap(), old.unwrap());
            let scale = old.iter().fold(0.0f64, |a, v| a.max(v.norm()));
            assert!(scale > 0.0);
            for (lanes, new) in [("dispatched", new), ("portable", portable(&m, &u))] {
                for (n, (a, b)) in new.iter().zip(&old).enumerate() {
                    let d = (a - b).norm();
                    assert!(
                        d <= 1e-12 * scale,
                        "{name} {lanes} mixed={mixed} node {n}: {a} vs {b} (scale {scale:e})"
                    );
                }
            }
        }
    }
}

/// `J` (and for T4ANP `J̄`, the nodal averages taken over the tets of the same solid) of
/// every element computed here from the reference data; the lowest element index with a
/// value not > 0.
fn brute_force_first_inversion(m: &Model, u: &[Vector3<f64>]) -> Option<usize> {
    let tj: Vec<f64> =
        m.elements.tets.iter().map(|t| det3(&deformation_gradient(u, &t.nodes, &t.g))).collect();
    // (node, solid) -> (Σ V J, Σ V)
    let mut sums: std::collections::HashMap<(u32, u32), (f64, f64)> = Default::default();
    for (t, &j) in m.elements.tets.iter().zip(&tj) {
        for &n in &t.nodes {
            let s = sums.entry((n, t.mat)).or_default();
            s.0 += t.vol * j;
            s.1 += t.vol;
        }
    }
    let anp = m.options.tet == TetFormulation::T4Anp;
    let mut bad: Vec<usize> = Vec::new();
    for (k, t) in m.elements.tets.iter().enumerate() {
        let nodal = |n: &u32| {
            let (vj, v) = sums[&(*n, t.mat)];
            vj / v
        };
        let jbar = t.nodes.iter().map(nodal).sum::<f64>() / 4.0;
        if tj[k] <= 0.0 || (anp && jbar <= 0.0) {
            bad.push(m.elements.tet_elem[k] as usize);
        }
    }
    for (k, h) in m.elements.hexes.iter().enumerate() {
        if det3(&deformation_gradient(u, &h.nodes, &h.g)) <= 0.0 {
            bad.push(m.elements.hex_elem[k] as usize);
        }
    }
    bad.into_iter().min()
}

#[test]
fn inversion_is_reported_with_the_lowest_element_index() {
    for (name, tets, tet) in CASES {
        let n = 4;
        let mesh = jittered_box(n, tets);
        let m = model(&mesh, tet, false);
        let h = 1.0 / n as f64;
        let mut u = deformation(&mesh);
        // Push two interior nodes far through their neighbours.
        for (node, d) in [
            (bs_mesh::structured::grid_index(n, 3, 2, 3), 6.0),
            (bs_mesh::structured::grid_index(n, 1, 2, 1), -6.0),
        ] {
            u[node] += Vector3::new(d * h, 0.3 * d * h, 0.0);
        }
        let expected = brute_force_first_inversion(&m, &u).expect("some element is inverted");
        let (new, old) = both(&m, &u);
        let (new, old) = (new.unwrap_err(), old.unwrap_err());
        assert_eq!(new.element, expected, "{name}");
        assert_eq!(old.element, expected, "{name}");
        assert_eq!(new.element_id, m.element_ids()[expected], "{name}");
        assert!(new.jacobian <= 0.0 || new.jacobian.is_nan(), "{name}: {new:?}");
        assert!(
            (new.jacobian - old.jacobian).abs() <= 1e-12 * old.jacobian.abs().max(1.0),
            "{name}: {new:?} vs {old:?}"
        );
    }
}

#[test]
fn forces_are_bit_identical_for_1_and_2_threads_with_mixed_laws() {
    for (name, tets, tet) in CASES {
        let mesh = jittered_box(6, tets);
        let u = deformation(&mesh);
        let m = model(&mesh, tet, true);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
                let mut f = vec![Vector3::zeros(); m.node_count()];
                m.internal_forces_into(&u, &mut m.workspace(), &mut f).unwrap();
                f
            })
        };
        let (a, b) = (run(1), run(2));
        for (x, y) in a.iter().zip(&b) {
            for c in 0..3 {
                assert_eq!(x[c].to_bits(), y[c].to_bits(), "{name}");
            }
        }
    }
}

/// T4ANP averaging groups: one per node on a one-solid mesh, numbered as the nodes (so its
/// forces are those of the plain nodal average); on a mesh of two solids, one more per node
/// that has tets of both, and every tet's corners in groups of its own solid.
#[test]
fn anp_groups_split_nodes_shared_by_two_solids() {
    let mesh = jittered_box(3, true);
    let one = model(&mesh, TetFormulation::T4Anp, false);
    assert_eq!(one.elements.anp_groups(), one.node_count());
    assert!(one.elements.tets.iter().all(|t| t.anp == t.nodes));
    let two = model(&mesh, TetFormulation::T4Anp, true);
    let mut solids_of = vec![std::collections::BTreeSet::new(); two.node_count()];
    for t in &two.elements.tets {
        for &n in &t.nodes {
            solids_of[n as usize].insert(t.mat);
        }
    }
    let extra: usize = solids_of.iter().map(|s| s.len().saturating_sub(1)).sum();
    assert!(extra > 0, "the mixed model has interface nodes");
    assert_eq!(two.elements.anp_groups(), two.node_count() + extra);
    let mut group_solid = vec![None; two.elements.anp_groups()];
    for t in &two.elements.tets {
        for (&g, &n) in t.anp.iter().zip(&t.nodes) {
            assert!(g as usize == n as usize || g as usize >= two.node_count());
            let s = group_solid[g as usize].get_or_insert(t.mat);
            assert_eq!(*s, t.mat, "group {g} mixes solids");
        }
    }
}
