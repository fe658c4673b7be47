//! DR and the Newton reference agree on the same mesh and loads: a 10 mm cube, bottom
//! clamped, top pushed down by 20% of the height (top nodes also held laterally).

use bs_dr::{DrParams, DynamicRelaxation, Loads, Newton, NewtonParams, NoContact, Solver};
use bs_material::Material;
use bs_mesh::{Mesh, Vector3};

use crate::common::*;

fn clamp_and_push(mesh: &Mesh, size: f64, push: f64) -> Loads {
    let mut loads = Loads::new(mesh.nodes.len());
    for (i, p) in mesh.nodes.iter().enumerate() {
        if p.z.abs() < 1e-12 {
            loads.fix_node(i).unwrap();
        }
        if (p.z - size).abs() < 1e-12 {
            loads.prescribe_node(i, Vector3::new(0.0, 0.0, -push)).unwrap();
        }
    }
    loads
}

#[test]
fn dr_matches_newton_within_1e_3_mm() {
    let size = 10.0; // mm
    for tech in [Tech::T4, Tech::H8] {
        let (mesh, model) =
            cube_model(tech, 4, size, 0.2, Material::neo_hookean(3000.0, 0.45).unwrap());
        let loads = clamp_and_push(&mesh, size, 0.2 * size);
        let newton = Newton::new(NewtonParams::default())
            .solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}))
            .unwrap();
        // DR tolerance 1e-7 × 2 mm: the termination estimate is far below the 1e-3 mm asserted.
        let dr = DynamicRelaxation::new(DrParams { tolerance: 1e-7, ..Default::default() })
            .solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}))
            .unwrap();
        let diff = max_diff(&newton.displacements, &dr.displacements);
        // The answer is not trivial: the sides bulge by a sizeable fraction of a mm.
        let bulge = dr.displacements.iter().fold(0.0f64, |m, v| m.max(v.x.abs().max(v.y.abs())));
        assert!(bulge > 0.3, "{tech:?}: lateral bulge {bulge}");
        assert!(diff <= 1e-3, "{tech:?}: DR vs Newton max nodal difference {diff:e} mm");
        assert!(
            newton.report.iterations >= 10 && newton.report.iterations <= 10 * 8,
            "{:?}",
            newton.report
        );
    }
}

#[test]
fn newton_rejects_anp() {
    let (mesh, model) =
        cube_model(Tech::T4Anp, 2, 1.0, 0.0, Material::neo_hookean(3000.0, 0.45).unwrap());
    let loads = clamp_and_push(&mesh, 1.0, 0.1);
    let r =
        Newton::default().solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}));
    assert!(
        matches!(r, Err(bs_dr::NewtonError::Unsupported { what: "T4ANP tetrahedra", .. })),
        "{r:?}"
    );
}

/// Behind the `Solver` trait each solver gives the same displacements as its own `solve`,
/// and its own info becomes the common report (steps, error, evaluations).
#[test]
fn solvers_are_swappable_behind_the_trait() {
    let (mesh, model) =
        cube_model(Tech::H8, 2, 1.0, 0.1, Material::neo_hookean(3000.0, 0.45).unwrap());
    let loads = clamp_and_push(&mesh, 1.0, 0.05);
    let dr = DynamicRelaxation::default();
    let newton = Newton::default();
    let own_dr =
        dr.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
    let own_newton =
        newton.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
    let solvers: [&dyn Solver; 2] = [&dr, &newton];
    for s in solvers {
        let common =
            s.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
        let (u, steps, evaluations) = match s.name() {
            "dr" => (&own_dr.displacements, own_dr.report.steps, own_dr.report.steps),
            _ => (
                &own_newton.displacements,
                own_newton.report.iterations,
                own_newton.report.force_evaluations,
            ),
        };
        assert_eq!(&common.displacements, u, "{}", s.name());
        assert_eq!(common.report.solver, s.name());
        assert_eq!((common.report.steps, common.report.force_evaluations), (steps, evaluations));
    }
}
