//! Bit-identical results for 1 and 2 threads (explicit rayon pools).

use bs_dr::{DrParams, DynamicRelaxation, Loads, NoContact};
use bs_material::Material;
use bs_mesh::Vector3;

use crate::common::*;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

#[test]
fn internal_forces_are_bit_identical_for_1_and_2_threads() {
    // 8³ cells: 3072 tets / 512 hexes and 729 nodes, enough for rayon to split the element
    // and node loops into several tasks.
    for tech in ALL_TECH {
        let (mesh, model) =
            cube_model(tech, 8, 1.0, 0.2, Material::neo_hookean(3000.0, 0.45).unwrap());
        let mut rng = Rng::new(11);
        let u: Vec<Vector3<f64>> = mesh
            .nodes
            .iter()
            .map(|_| {
                Vector3::new(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5) * 0.01
            })
            .collect();
        let run = |threads: usize| {
            pool(threads).install(|| {
                let mut ws = model.workspace();
                let mut f = vec![Vector3::zeros(); mesh.nodes.len()];
                model.internal_forces_into(&u, &mut ws, &mut f).unwrap();
                f
            })
        };
        let (f1, f2) = (run(1), run(2));
        assert!(f1.iter().any(|v| v.norm() > 0.0));
        for (a, b) in f1.iter().zip(&f2) {
            for c in 0..3 {
                assert_eq!(a[c].to_bits(), b[c].to_bits(), "{tech:?}");
            }
        }
        // Forces balance: the sum of internal forces of a free body is zero (to round-off
        // relative to the largest nodal force).
        let sum: Vector3<f64> = f1.iter().sum();
        let fmax = f1.iter().fold(0.0f64, |m, v| m.max(v.amax()));
        assert!(sum.amax() <= 1e-10 * fmax * mesh.nodes.len() as f64, "{tech:?}: {sum}");
    }
}

#[test]
fn dr_history_is_bit_identical_for_1_and_2_threads() {
    let (mesh, model) =
        cube_model(Tech::T4Anp, 8, 1.0, 0.2, Material::neo_hookean(3000.0, 0.45).unwrap());
    let mut loads = Loads::new(mesh.nodes.len());
    for (i, p) in mesh.nodes.iter().enumerate() {
        if p.z.abs() < 1e-12 {
            loads.fix_node(i).unwrap();
        }
        if (p.z - 1.0).abs() < 1e-12 {
            loads.prescribe(i, 2, -0.1).unwrap();
        }
    }
    let params = DrParams { max_steps: 60, ramp_steps: 40, ..Default::default() };
    let run = |threads: usize| {
        pool(threads).install(|| {
            let mut trace = Vec::new();
            let r = DynamicRelaxation::new(params).solve(bs_dr::Problem::new(
                &model,
                &loads,
                &mut NoContact,
                &mut |p| {
                    trace.push(p.max_displacement.to_bits());
                },
            ));
            assert!(matches!(r, Err(bs_dr::DrError::NoConvergence { steps: 60, .. })), "{r:?}");
            trace
        })
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.len(), 60);
    assert_eq!(a, b);
}
