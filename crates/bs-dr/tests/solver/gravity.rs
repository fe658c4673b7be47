//! A body force through every solver and element: a laterally confined Neo-Hookean column
//! under its own weight, dry and half submerged in a fluid, against the closed form
//! (`bs_material::closed_form::confined_column_displacement`), converging on refinement.

use bs_dr::{
    BodyForce, Buoyancy, DrParams, DynamicRelaxation, Loads, Model, ModelOptions, Newton,
    NewtonKrylov, NewtonKrylovParams, NoContact, Solid, Solver, TetFormulation,
};
use bs_material::Material;
use bs_material::closed_form::confined_column_displacement;
use bs_mesh::{Mesh, Point3, Vector3, structured};

use crate::common::Tech;

const WIDTH: f64 = 10.0; // mm
const HEIGHT: f64 = 80.0; // mm
/// Brain tissue and cerebrospinal fluid (kg/m³), gravity 9.81 m/s²: in N/mm³·1e6 = Pa/mm,
/// `ρ g · 10⁻³`.
const RHO: f64 = 1040.0;
const RHO_FLUID: f64 = 1007.0;
const G: f64 = 9.81e-3;

fn material() -> Material {
    Material::neo_hookean(3000.0, 0.45).unwrap()
}

/// `layers` elements high and `layers / 4` wide (refined in every direction).
fn column(tech: Tech, layers: usize) -> (Mesh, Model) {
    let mesh = structured::cuboid_mesh(
        [layers / 4, layers / 4, layers],
        [WIDTH, WIDTH, HEIGHT],
        tech != Tech::H8,
    );
    let tet = if tech == Tech::T4Anp { TetFormulation::T4Anp } else { TetFormulation::T4 };
    let solid = Solid { material: material(), density: RHO };
    let model = Model::uniform(&mesh, solid, ModelOptions { tet, ..Default::default() }).unwrap();
    (mesh, model)
}

/// Rollers on the sides and the base; the weight (and the fluid below mid-height).
fn loads(mesh: &Mesh, model: &Model, submerged: bool) -> Loads {
    let mut loads = Loads::new(mesh.nodes.len());
    for (i, p) in mesh.nodes.iter().enumerate() {
        for c in 0..2 {
            if p[c].abs() < 1e-9 || (p[c] - WIDTH).abs() < 1e-9 {
                loads.fix(i, c).unwrap();
            }
        }
        if p.z.abs() < 1e-9 {
            loads.fix(i, 2).unwrap();
        }
    }
    let down = Vector3::new(0.0, 0.0, -1.0);
    let buoyancy = submerged.then_some(Buoyancy {
        per_volume: -down * RHO_FLUID * G,
        level: Point3::new(0.0, 0.0, HEIGHT / 2.0),
        down,
    });
    let body = BodyForce { per_solid: vec![down * RHO * G], buoyancy };
    loads.set_forces(model.body_loads(&body).unwrap()).unwrap();
    loads
}

/// The largest error of the axial displacement at the nodes, against the closed form, and
/// the settlement of the top.
fn error(mesh: &Mesh, u: &[Vector3<f64>], submerged: bool) -> (f64, f64) {
    let weight = |z: f64| {
        if submerged && z < HEIGHT / 2.0 { (RHO - RHO_FLUID) * G } else { RHO * G }
    };
    let z: Vec<f64> = mesh.nodes.iter().map(|p| p.z).collect();
    let exact = confined_column_displacement(&material(), HEIGHT, &weight, 0.0, &z).unwrap();
    let err = u.iter().zip(&exact).fold(0.0f64, |m, (v, e)| m.max((v.z - e).abs()));
    (err, -exact[z.iter().position(|&h| h == HEIGHT).unwrap()])
}

fn solve(solver: &dyn Solver, model: &Model, loads: &Loads) -> Vec<Vector3<f64>> {
    solver
        .solve(bs_dr::Problem::new(model, loads, &mut NoContact, &mut |_| {}))
        .unwrap()
        .displacements
}

#[test]
fn a_confined_column_settles_under_its_weight_as_the_closed_form_on_every_element() {
    let nk = NewtonKrylov::new(NewtonKrylovParams { tolerance: 1e-9, ..Default::default() });
    for tech in [Tech::T4, Tech::T4Anp, Tech::H8] {
        for submerged in [false, true] {
            let mut errors = Vec::new();
            for layers in [4, 8, 16] {
                let (mesh, model) = column(tech, layers);
                let u = solve(&nk, &model, &loads(&mesh, &model, submerged));
                errors.push(error(&mesh, &u, submerged));
            }
            let (e, settlement) = (errors.iter().map(|e| e.0).collect::<Vec<_>>(), errors[0].1);
            // The column settles by 3.6 % of its height dry (2.85 mm of 80), 2.7 % with its
            // lower half buoyant: strains the large-strain law feels.
            assert!(settlement > if submerged { 2.0 } else { 2.8 }, "{settlement}");
            // Each halving of the elements cuts the largest nodal error at least twofold
            // (measured: H8 fourfold, 3e-4 → 2e-5 mm, its mean strain exact for this field;
            // T4 2.3–2.7×, T4ANP 2.9–3.6×, the tetrahedra's lateral stiffness converging
            // too) and leaves it below 1 % of the settlement on 16 layers (T4 0.47 %).
            assert!(e[1] < e[0] / 2.0 && e[2] < e[1] / 2.0, "{tech:?} {submerged}: {e:?}");
            assert!(e[2] < 1e-2 * settlement, "{tech:?} {submerged}: {e:?} of {settlement}");
        }
    }
}

#[test]
fn dr_and_newton_carry_the_weight_to_the_same_answer_as_newton_krylov() {
    let (mesh, model) = column(Tech::T4, 8);
    let loads = loads(&mesh, &model, true);
    let nk = solve(
        &NewtonKrylov::new(NewtonKrylovParams { tolerance: 1e-10, ..Default::default() }),
        &model,
        &loads,
    );
    // Tolerances relative to the load scale (here the mesh diagonal, 43 mm): 1e-9 is 4e-8 mm.
    let dr = solve(
        &DynamicRelaxation::new(DrParams { tolerance: 1e-9, ..Default::default() }),
        &model,
        &loads,
    );
    let newton = solve(&Newton::default(), &model, &loads);
    let diff = |a: &[Vector3<f64>], b: &[Vector3<f64>]| {
        a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).amax()))
    };
    assert!(diff(&nk, &dr) < 1e-5, "DR: {:e}", diff(&nk, &dr));
    assert!(diff(&nk, &newton) < 1e-5, "Newton: {:e}", diff(&nk, &newton));
}

/// The column's loads with its weight (and the fluid's) scaled by `factor`.
fn loads_scaled(mesh: &Mesh, model: &Model, factor: f64) -> Loads {
    let mut l = loads(mesh, model, true);
    let forces = l.forces().iter().map(|f| f * factor).collect();
    l.set_forces(forces).unwrap();
    l
}

#[test]
fn the_linear_response_to_more_weight_is_the_difference_of_two_solves() {
    // At the settled column (2.7 % strain, the large-strain law's tangent), the response to
    // 1 % more weight through the converged tangent against the central difference of two
    // nonlinear solves at ±1 % (second-order accurate: ~1e-4 of the response; the solves'
    // tolerance 1e-10 of the load scale adds 4e-9 mm / 0.01).
    let params = NewtonKrylovParams { tolerance: 1e-10, ..Default::default() };
    let nk = NewtonKrylov::new(params);
    for tech in [Tech::T4, Tech::T4Anp] {
        let (mesh, model) = column(tech, 8);
        let at = |f: f64| {
            let l = loads_scaled(&mesh, &model, f);
            let prep = nk.prepare(&model, &l).unwrap();
            nk.solve_prepared(&prep, bs_dr::Problem::new(&model, &l, &mut NoContact, &mut |_| {}))
                .unwrap()
                .displacements
        };
        let (u, up, down) = (at(1.0), at(1.01), at(0.99));
        let loads = loads_scaled(&mesh, &model, 1.0);
        let prep = nk.prepare(&model, &loads).unwrap();
        // The residual is internal minus dead forces: 1 % more weight lowers it by 1 % of them.
        let change: Vec<Vector3<f64>> = loads.forces().iter().map(|f| -f * 0.01).collect();
        let mut response = vec![Vector3::zeros(); u.len()];
        // Five changes through the batched path (a batch of four and one alone): the same
        // change gives the same response bit for bit, a scaled one the scaled response (to
        // 1e-6 of it: the tangent product is a force difference whose step follows the
        // vector's size, good to √ε ≈ 1.5e-8 of it before the conditioning), and no change
        // none.
        let scales = [1.0, 2.0, 0.0, -0.5, 1.0];
        let changes: Vec<Vec<Vector3<f64>>> =
            scales.iter().map(|s| change.iter().map(|c| c * *s).collect()).collect();
        let mut many = vec![vec![Vector3::zeros(); u.len()]; scales.len()];
        // Loose responses carried on to 1e-10 from where they stopped, and one already there
        // left alone.
        let mut loose = vec![vec![Vector3::zeros(); u.len()]; 2];
        let (info, infos, refined, kept) = nk
            .with_response(&model, &loads, &prep, &u, &mut NoContact, &mut bs_dr::NoData, |r| {
                let one = r.solve(&change, &mut response, 1e-10)?;
                let all = r.solve_all(&changes, &mut many, 1e-10)?;
                let pair = [change.clone(), changes[3].clone()];
                r.solve_all(&pair, &mut loose, 1e-2)?;
                let refined = r.refine_all(&pair, &mut loose, 1e-10)?;
                let before = loose[0].clone();
                let kept = r.refine_all(&pair[..1], &mut loose[..1], 0.5)?;
                assert_eq!(loose[0], before, "a response already within 0.5 is left alone");
                Ok::<_, bs_dr::nk::NewtonKrylovError>((one, all, refined, kept))
            })
            .unwrap()
            .unwrap();
        assert!(refined.iter().all(|i| i.converged && i.iterations > 0), "{refined:?}");
        assert_eq!(kept[0].iterations, 0, "{kept:?}");
        assert!(info.converged, "{tech:?}: {info:?}");
        assert_eq!(many[0], response, "{tech:?}: the batch's first response");
        assert_eq!(many[4], response, "{tech:?}: the lone fifth response");
        let size = response.iter().fold(0.0f64, |m, v| m.max(v.amax()));
        for (s, m) in scales.iter().zip(&many) {
            let off = m.iter().zip(&response).fold(0.0f64, |a, (m, r)| a.max((m - r * *s).amax()));
            assert!(off <= 1e-6 * size * s.abs(), "{tech:?}: ×{s} off by {off:e} of {size:e}");
        }
        assert!(infos.iter().all(|i| i.converged), "{tech:?}: {infos:?}");
        // Refined to the direct solves' 1e-10: the same responses to the solves' accuracy.
        for (l, s) in loose.iter().zip([1.0, -0.5]) {
            let off = l.iter().zip(&response).fold(0.0f64, |a, (l, r)| a.max((l - r * s).amax()));
            assert!(off <= 1e-6 * size, "{tech:?}: refined ×{s} off by {off:e} of {size:e}");
        }
        let scale = response.iter().fold(0.0f64, |m, v| m.max(v.amax()));
        let diff = response
            .iter()
            .zip(up.iter().zip(&down))
            .fold(0.0f64, |m, (r, (a, b))| m.max((r - (a - b) / 2.0).amax()));
        // The response is about 1 % of the settlement (2 mm): 0.02 mm.
        assert!(scale > 0.015, "{tech:?}: {scale}");
        assert!(diff < 1e-3 * scale, "{tech:?}: {diff:e} of {scale:e}");
    }
}
