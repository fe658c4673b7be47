//! The preconditioner against Jacobi on a nearly incompressible block, and its symmetry.

use bs_material::Material;
use bs_mesh::Vector3;
use bs_mesh::structured::box_mesh;
use nalgebra::Matrix3;

use super::projector::projected_inverse;
use super::{Projector, TwoLevel, TwoLevelParams};
use crate::linalg::krylov::Gmres;
use crate::linalg::sparse::dot;
use crate::{Model, ModelOptions, Solid, TetFormulation};

/// The preconditioner of `m`'s `K₀` with constraints `fixed`.
fn preconditioner(m: &Model, fixed: &Projector) -> TwoLevel {
    TwoLevel::new(
        m.linear_stiffness(),
        m.reference(),
        m.mean_edge(),
        fixed,
        TwoLevelParams::default(),
    )
    .unwrap()
}

fn model(tet: TetFormulation, cells: usize) -> Model {
    model_with(tet, cells, 0.49)
}

/// A jittered `cells`³ block of side 10 with Poisson's ratio `nu`.
fn model_with(tet: TetFormulation, cells: usize, nu: f64) -> Model {
    let mut mesh = box_mesh(cells, 10.0, true);
    let h = 10.0 / cells as f64;
    for (i, p) in mesh.nodes.iter_mut().enumerate() {
        let interior = [p.x, p.y, p.z].iter().all(|&c| c > 1e-9 && c < 10.0 - 1e-9);
        if interior {
            let t = i as f64;
            p.x += 0.15 * h * (1.7 * t).sin();
            p.y += 0.15 * h * (2.3 * t).cos();
            p.z += 0.15 * h * (0.9 * t).sin();
        }
    }
    let solid = Solid { material: Material::neo_hookean(3000.0, nu).unwrap(), density: 1000.0 };
    Model::uniform(&mesh, solid, ModelOptions { tet, hourglass: 0.1 }).unwrap()
}

fn bottom_fixed(m: &Model) -> Projector {
    let mut p = Projector::free(m.node_count());
    for (a, x) in m.reference().iter().enumerate() {
        if x.z < 1e-9 {
            p.set(a, &[Vector3::x(), Vector3::y(), Vector3::z()]);
        }
    }
    p
}

fn iterations(m: &Model, two_level: bool) -> (usize, f64) {
    let fixed = bottom_fixed(m);
    let tl = preconditioner(m, &fixed);
    let con = tl.constraints();
    let n = m.node_count();
    let mut b: Vec<Vector3<f64>> =
        m.reference().iter().map(|x| Vector3::new(0.1 * x.z, 0.0, -0.05 * x.x)).collect();
    fixed.apply(&mut b);
    let k = m.linear_stiffness();
    let mut ks = k.scratch();
    let mut ts = tl.scratch();
    let mut op = |x: &[Vector3<f64>], y: &mut [Vector3<f64>]| {
        k.mul(x, y, &mut ks);
        fixed.apply(y);
    };
    let diag: Vec<Matrix3<f64>> =
        (0..n).map(|a| projected_inverse(&k.diagonal(a), &fixed.matrix[a])).collect();
    let mut prec = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| {
        if two_level {
            tl.apply(&con, r, z, &mut ts);
        } else {
            for a in 0..n {
                z[a] = diag[a] * r[a];
            }
        }
    };
    let mut x = vec![Vector3::zeros(); n];
    let info = Gmres::new(n, 60).solve(&mut op, &mut prec, &b, &mut x, 1e-8, 3000);
    assert!(info.converged, "{info:?}");
    (info.iterations, info.relative_residual)
}

#[test]
fn two_level_cuts_the_iterations_of_a_nearly_incompressible_block() {
    for tet in [TetFormulation::T4, TetFormulation::T4Anp] {
        let m = model(tet, 8);
        let (jacobi, _) = iterations(&m, false);
        let (tl, _) = iterations(&m, true);
        // Measured: T4 66 vs 1463, T4ANP 41 vs 871 (8³ cells, ν = 0.49).
        assert!(tl * 10 <= jacobi, "{tet:?}: two-level {tl} vs Jacobi {jacobi} iterations");
        assert!(tl <= 80, "{tet:?}: two-level {tl} iterations");
    }
}

#[test]
fn the_prolongator_feels_the_nodal_volumetric_stiffness() {
    // T4ANP's volumetric stiffness is a sum over nodes, outside the element matrices; the
    // prolongator is smoothed with it too, so that the coarse space carries it. Measured
    // (8³ block, GMRES to 1e-8): 41 and 133 iterations at ν = 0.49 and 0.499; smoothed with
    // the element part only (the version before), 50 and 163, which these bounds refuse.
    for (nu, bound) in [(0.49, 45), (0.499, 145)] {
        let (tl, _) = iterations(&model_with(TetFormulation::T4Anp, 8, nu), true);
        assert!(tl <= bound, "ν = {nu}: {tl} iterations (at most {bound})");
    }
}

#[test]
fn the_cycle_is_symmetric_and_positive() {
    let m = model(TetFormulation::T4Anp, 5);
    let fixed = bottom_fixed(&m);
    let tl = preconditioner(&m, &fixed);
    let con = tl.constraints();
    let n = m.node_count();
    let mut x: Vec<Vector3<f64>> =
        (0..n).map(|a| Vector3::new((a as f64).sin(), 0.5, (0.3 * a as f64).cos())).collect();
    let mut y: Vec<Vector3<f64>> =
        (0..n).map(|a| Vector3::new(1.0, (1.7 * a as f64).cos(), -0.2)).collect();
    fixed.apply(&mut x);
    fixed.apply(&mut y);
    let (mut bx, mut by) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    let mut s = tl.scratch();
    tl.apply(&con, &x, &mut bx, &mut s);
    tl.apply(&con, &y, &mut by, &mut s);
    let (xby, ybx) = (dot(&x, &by), dot(&y, &bx));
    assert!((xby - ybx).abs() <= 1e-9 * xby.abs().max(ybx.abs()), "{xby} vs {ybx}");
    assert!(dot(&x, &bx) > 0.0 && dot(&y, &by) > 0.0);
    // The result stays in the admissible subspace.
    for a in 0..n {
        assert!((fixed.matrix[a] * bx[a] - bx[a]).norm() <= 1e-14 * bx[a].norm().max(1.0));
    }
}
