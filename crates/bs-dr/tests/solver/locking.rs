//! Volumetric locking at ν = 0.499: indentation of an irregular block (4³ cells, jittered
//! interior nodes), bottom clamped, a 3×3-node patch in the middle of the top pushed down by
//! 5% of the height. The reaction force on the patch measures the stiffness.

use bs_dr::{DrParams, DynamicRelaxation, Loads, Model, Newton, NoContact};
use bs_material::Material;
use bs_mesh::{Mesh, Vector3};

use crate::common::*;

const DEPTH: f64 = 0.05;

fn indentation(mesh: &Mesh) -> (Loads, Vec<usize>) {
    let mut loads = Loads::new(mesh.nodes.len());
    let mut patch = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        if p.z.abs() < 1e-12 {
            loads.fix_node(i).unwrap();
        }
        if (p.z - 1.0).abs() < 1e-12 && (p.x - 0.5).abs() < 0.26 && (p.y - 0.5).abs() < 0.26 {
            loads.prescribe_node(i, Vector3::new(0.0, 0.0, -DEPTH)).unwrap();
            patch.push(i);
        }
    }
    assert_eq!(patch.len(), 9);
    (loads, patch)
}

fn reaction(model: &Model, u: &[Vector3<f64>], patch: &[usize]) -> f64 {
    let mut f = vec![Vector3::zeros(); u.len()];
    model.internal_forces_into(u, &mut model.workspace(), &mut f).unwrap();
    patch.iter().map(|&i| f[i].z).sum::<f64>().abs()
}

#[test]
fn t4_locks_and_t4anp_does_not() {
    let material = Material::neo_hookean(3000.0, 0.499).unwrap();
    let mut results = Vec::new();
    for tech in ALL_TECH {
        let (mesh, model) = cube_model(tech, 4, 1.0, 0.2, material);
        let (loads, patch) = indentation(&mesh);
        let sol = if tech == Tech::T4Anp {
            DynamicRelaxation::new(DrParams::default())
                .solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}))
                .unwrap()
                .into_common()
        } else {
            Newton::default()
                .solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}))
                .unwrap()
                .into_common()
        };
        results.push((tech, reaction(&model, &sol.displacements, &patch), sol.report.steps));
    }
    let r = |t: Tech| results.iter().find(|x| x.0 == t).unwrap().1;
    let (t4, anp, h8) = (r(Tech::T4), r(Tech::T4Anp), r(Tech::H8));
    // Measured (this mesh): T4 351.6, T4ANP 171.6, H8 138.3 (force units: Pa × length²).
    // Reference: H8 mean strain + Newton on refined meshes of the same block and indenter
    // area: 8³ cells 125.6, 12³ cells 121.25 (converging from above; recorded from a one-off
    // run of this problem with `hex_cube(n, 1.0, 0.2, 7)`, too slow for a debug test).
    // T4ANP on 8³ cells gives 136.8 (13% above the 12³ reference).
    const REFERENCE: f64 = 121.25;
    // Locking: T4 is ~2× stiffer than T4ANP and ~2.9× the reference.
    assert!(t4 > 1.8 * anp, "T4 {t4} vs T4ANP {anp}");
    assert!(t4 > 2.5 * REFERENCE, "T4 {t4}");
    // T4ANP on this coarse mesh is within 45% of the converged answer (measured 42%: the
    // indenter edge is a stress singularity that a 4³ mesh resolves poorly) and within 30%
    // of H8 on the same nodes (measured 24%), where T4 is 190% and 154% off.
    assert!((anp - REFERENCE).abs() < 0.45 * REFERENCE, "T4ANP {anp}");
    assert!((anp - h8).abs() < 0.30 * h8, "T4ANP {anp} vs H8 {h8}");
    // The solve itself is sane: H8 on this mesh is above the refined answer (convergence
    // from above) by less than 20% (measured 14%).
    assert!(h8 > REFERENCE && h8 < 1.2 * REFERENCE, "H8 {h8}");
}
