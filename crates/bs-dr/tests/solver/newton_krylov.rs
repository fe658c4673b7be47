//! The Newton–Krylov solver against the reference solvers (Newton without contact, DR with
//! kinematic contact), on smooth and polyhedral obstacles, its error estimate against a much
//! tighter solve, its determinism and its guards.

use bs_dr::{
    Contact, ContactProjection, ContactReport, ContinuationParams, DrParams, DynamicRelaxation,
    LoadFailure, Loads, Newton, NewtonKrylov, NewtonKrylovParams, NewtonParams, NoContact,
    SolveError, Solver, SurfaceFeature,
};
use bs_material::Material;
use bs_mesh::{Point3, Vector3};

use crate::common::*;

fn nk(tolerance: f64) -> NewtonKrylov {
    NewtonKrylov::new(NewtonKrylovParams { tolerance, ..Default::default() })
}

/// Bottom face clamped, top face pushed down by `push` (all three components prescribed).
fn clamp_and_push(mesh: &bs_mesh::Mesh, size: f64, push: f64) -> Loads {
    let mut loads = Loads::new(mesh.nodes.len());
    for (i, p) in mesh.nodes.iter().enumerate() {
        if p.z.abs() < 1e-12 {
            loads.fix_node(i).unwrap();
        } else if (p.z - size).abs() < 1e-12 {
            loads.prescribe_node(i, Vector3::new(0.0, 0.0, -push)).unwrap();
        }
    }
    loads
}

#[test]
fn matches_newton_without_contact() {
    // T4 and H8 (Newton's elements), ν = 0.45, 20 % compression: large deformation.
    for tech in [Tech::T4, Tech::H8] {
        let (mesh, model) =
            cube_model(tech, 4, 1.0, 0.2, Material::neo_hookean(3000.0, 0.45).unwrap());
        let loads = clamp_and_push(&mesh, 1.0, 0.2);
        let newton = Newton::new(NewtonParams { tolerance: 1e-11, ..Default::default() })
            .solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}))
            .unwrap();
        let sol = nk(1e-8)
            .solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}))
            .unwrap();
        let diff = max_diff(&sol.displacements, &newton.displacements);
        // Both converged far below the difference that matters; NK's estimate bounds it.
        assert!(
            diff <= sol.report.err + 1e-8,
            "{tech:?}: {diff:e} vs estimate {:e}",
            sol.report.err
        );
        assert!(sol.report.steps <= 12, "{tech:?}: {} Newton iterations", sol.report.steps);
        assert!(
            sol.report.linear_iterations > 0 && sol.report.force_evaluations > sol.report.steps
        );
    }
}

#[test]
fn t4anp_matches_dynamic_relaxation_without_contact() {
    // No Newton reference for T4ANP (its nodal averaging couples elements): DR, tight.
    let (mesh, model) =
        cube_model(Tech::T4Anp, 4, 1.0, 0.2, Material::neo_hookean(3000.0, 0.49).unwrap());
    let loads = clamp_and_push(&mesh, 1.0, 0.15);
    let dr = DynamicRelaxation::new(DrParams { tolerance: 1e-9, ..Default::default() })
        .solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {}))
        .unwrap();
    let sol =
        nk(1e-9).solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
    let diff = max_diff(&sol.displacements, &dr.displacements);
    assert!(diff <= 1e-7, "{diff:e}");
    // The prescribed components are exactly their values.
    for i in 0..mesh.nodes.len() {
        for c in 0..3 {
            if loads.is_constrained(i, c) {
                assert_eq!(sol.displacements[i][c], loads.value(i, c));
            }
        }
    }
}

/// The admissible region `{x : n_i · x ≤ d_i}` of one or two planes (a floor, or a floor and
/// a wall meeting at an edge), with exact projection and kinematic enforcement.
struct Planes {
    planes: Vec<(Vector3<f64>, f64)>,
    nodes: Vec<usize>,
    projected_on_edge: usize,
}

impl Planes {
    fn project_point(&self, p: &Point3<f64>) -> ContactProjection {
        let viol: Vec<bool> = self.planes.iter().map(|(n, d)| n.dot(&p.coords) > *d).collect();
        if !viol.iter().any(|&v| v) {
            return ContactProjection {
                point: *p,
                outside: false,
                feature: SurfaceFeature::Vertex,
            };
        }
        // Onto each violated plane alone; keep it if it satisfies the others.
        for (i, (n, d)) in self.planes.iter().enumerate() {
            if !viol[i] {
                continue;
            }
            let q = p - n * (n.dot(&p.coords) - d);
            let ok = self
                .planes
                .iter()
                .enumerate()
                .all(|(j, (m, e))| j == i || m.dot(&q.coords) <= e + 1e-12);
            if ok {
                return ContactProjection {
                    point: q,
                    outside: true,
                    feature: SurfaceFeature::Face(*n),
                };
            }
        }
        // Onto the edge of the two planes.
        let ((n1, d1), (n2, d2)) = (self.planes[0], self.planes[1]);
        let t = n1.cross(&n2).normalize();
        // Point of the edge: solve n1·q = d1, n2·q = d2, t·q = t·p.
        let m = nalgebra::Matrix3::from_rows(&[n1.transpose(), n2.transpose(), t.transpose()]);
        let q = m.try_inverse().unwrap() * Vector3::new(d1, d2, t.dot(&p.coords));
        ContactProjection {
            point: Point3::from(q),
            outside: true,
            feature: SurfaceFeature::Edge(t),
        }
    }
}

impl Contact for Planes {
    fn enforce(&mut self, positions: &mut [Point3<f64>]) -> ContactReport {
        let mut report = ContactReport::default();
        for &a in &self.nodes {
            let pr = self.project_point(&positions[a]);
            if pr.outside {
                report.nodes_in_contact += 1;
                report.max_penetration =
                    report.max_penetration.max((pr.point - positions[a]).norm());
                positions[a] = pr.point;
            }
        }
        report
    }

    fn nodes(&self) -> &[usize] {
        &self.nodes
    }

    fn project(&mut self, _k: usize, p: &Point3<f64>) -> Option<ContactProjection> {
        let pr = self.project_point(p);
        if matches!(pr.feature, SurfaceFeature::Edge(_)) {
            self.projected_on_edge += 1;
        }
        Some(pr)
    }
}

#[test]
fn frictionless_floor_acts_as_a_symmetry_plane() {
    // As the DR contact-seam test: uniaxial compression with x = 0 and y = 0 symmetry planes,
    // the floor z ≥ 0 in place of the z = 0 plane; exact answer = the symmetry-plane run.
    let (_, model, floor, bottom) = block_on_floor();
    let mut sym = floor.clone();
    for &i in &bottom {
        sym.fix(i, 2).unwrap();
    }
    let reference =
        nk(1e-10).solve(bs_dr::Problem::new(&model, &sym, &mut NoContact, &mut |_| {})).unwrap();
    // The floor governs the bottom nodes, some of which have fixed x or y (on the symmetry
    // planes): the contact directions are taken orthogonal to those.
    let mut contact =
        Planes { planes: vec![(-Vector3::z(), 0.0)], nodes: bottom, projected_on_edge: 0 };
    let sol =
        nk(1e-10).solve(bs_dr::Problem::new(&model, &floor, &mut contact, &mut |_| {})).unwrap();
    assert_eq!(sol.report.contact.nodes_in_contact, 16);
    let diff = max_diff(&sol.displacements, &reference.displacements);
    assert!(diff <= 1e-8, "floor vs symmetry plane: {diff:e}");
}

/// A block compressed on a frictionless floor next to a wall: it bulges into the wall and
/// its bottom slides into the corner, so nodes touch two faces and their edge, where a
/// single-plane linearisation alone would cycle. Newton–Krylov must give Dynamic
/// Relaxation's kinematic-contact answer.
#[test]
fn corner_of_floor_and_wall_matches_dynamic_relaxation() {
    let material = Material::neo_hookean(3000.0, 0.45).unwrap();
    let (mesh, model) = cube_model(Tech::T4Anp, 4, 1.0, 0.2, material);
    let mut loads = Loads::new(mesh.nodes.len());
    let mut slaves = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        if (p.z - 1.0).abs() < 1e-12 {
            loads.prescribe(i, 2, -0.2).unwrap(); // top pushed down, free to slide
        }
        if p.x.abs() < 1e-12 {
            loads.fix(i, 0).unwrap(); // symmetry planes x = 0 and y = 0: no rigid slide
        }
        if p.y.abs() < 1e-12 {
            loads.fix(i, 1).unwrap();
        }
        if (p.z - 1.0).abs() > 1e-12 && on_boundary(p, 1.0) {
            slaves.push(i);
        }
    }
    // Floor z ≥ −0.02 (the block drops onto it) and wall x ≤ 1.02 (the bulge reaches it).
    let planes = vec![(-Vector3::z(), 0.02), (Vector3::x(), 1.02)];
    let mut with_dr =
        Planes { planes: planes.clone(), nodes: slaves.clone(), projected_on_edge: 0 };
    let dr = DynamicRelaxation::new(DrParams { tolerance: 1e-9, ..Default::default() })
        .solve(bs_dr::Problem::new(&model, &loads, &mut with_dr, &mut |_| {}))
        .unwrap();
    let mut with_nk = Planes { planes, nodes: slaves, projected_on_edge: 0 };
    let sol =
        nk(1e-9).solve(bs_dr::Problem::new(&model, &loads, &mut with_nk, &mut |_| {})).unwrap();
    let diff = max_diff(&sol.displacements, &dr.displacements);
    assert!(diff <= 1e-6, "NK vs DR: {diff:e}");
    // Both faces and their edge were in play, and the answer is admissible.
    let on = |u: &[Vector3<f64>], pred: &dyn Fn(&Point3<f64>) -> bool| {
        mesh.nodes.iter().zip(u).filter(|(x, d)| pred(&(*x + *d))).count()
    };
    let u = &sol.displacements;
    let floor = on(u, &|q| (q.z + 0.02).abs() < 1e-9);
    let wall = on(u, &|q| (q.x - 1.02).abs() < 1e-9);
    let edge = on(u, &|q| (q.z + 0.02).abs() < 1e-9 && (q.x - 1.02).abs() < 1e-9);
    assert!(floor >= 10 && wall >= 3 && edge >= 1, "floor {floor}, wall {wall}, edge {edge}");
    assert!(with_nk.projected_on_edge > 0);
    for &a in &with_nk.nodes {
        let q = mesh.nodes[a] + u[a];
        assert!(q.z >= -0.02 - 1e-12 && q.x <= 1.02 + 1e-12, "node {a} penetrates: {q:?}");
    }
}

/// Rigid spherical cavity of radius `r` about the origin (smooth: every projection is onto
/// the curved surface, normal radial, curvature 1/r).
struct Sphere {
    radius: f64,
    nodes: Vec<usize>,
}

impl Contact for Sphere {
    fn enforce(&mut self, positions: &mut [Point3<f64>]) -> ContactReport {
        let mut report = ContactReport::default();
        for &a in &self.nodes {
            let d = positions[a].coords.norm();
            if d > self.radius {
                report.nodes_in_contact += 1;
                report.max_penetration = report.max_penetration.max(d - self.radius);
                positions[a] = Point3::from(positions[a].coords * (self.radius / d));
            }
        }
        report
    }

    fn nodes(&self) -> &[usize] {
        &self.nodes
    }

    fn project(&mut self, _k: usize, p: &Point3<f64>) -> Option<ContactProjection> {
        let d = p.coords.norm();
        let n = p.coords / d;
        Some(ContactProjection {
            point: Point3::from(n * self.radius),
            outside: d > self.radius,
            feature: SurfaceFeature::Curved { normal: n, curvature: 1.0 / self.radius },
        })
    }
}

/// The brain-shift-like sphere fixture of the contact-seam test (R = 10 mm, T4ANP,
/// ν = 0.45, stem fixed, cap pushed 1.5 mm into a rigid skull of the same radius).
fn sphere_case() -> (bs_dr::Model, Loads, Sphere) {
    use bs_dr::{Model, ModelOptions, Solid, TetFormulation};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/basic");
    let mesh = bs_mesh::io::read_mesh(&dir.join("sphere.msh")).unwrap();
    let material = Material::neo_hookean(3000.0, 0.45).unwrap();
    let model = Model::uniform(
        &mesh,
        Solid { material, density: 1000.0 },
        ModelOptions { tet: TetFormulation::T4Anp, ..Default::default() },
    )
    .unwrap();
    let radius = mesh.nodes.iter().fold(0.0f64, |m, p| m.max(p.coords.norm()));
    let mut loads = Loads::new(mesh.nodes.len());
    let mut slaves = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        let on_surface = p.coords.norm() > radius - 1e-6;
        if p.z < -8.5 {
            loads.fix_node(i).unwrap();
        } else if on_surface && p.z > 8.0 {
            loads.prescribe_node(i, Vector3::new(0.0, 0.0, -1.5)).unwrap();
        } else if on_surface {
            slaves.push(i);
        }
    }
    (model, loads, Sphere { radius, nodes: slaves })
}

#[test]
fn sphere_skull_matches_dynamic_relaxation() {
    let (model, loads, mut skull) = sphere_case();
    let dr = DynamicRelaxation::new(DrParams { tolerance: 1e-8, ..Default::default() })
        .solve(bs_dr::Problem::new(&model, &loads, &mut skull, &mut |_| {}))
        .unwrap();
    let sol = nk(1e-8).solve(bs_dr::Problem::new(&model, &loads, &mut skull, &mut |_| {})).unwrap();
    assert!(sol.report.contact.nodes_in_contact > 0);
    let diff = max_diff(&sol.displacements, &dr.displacements);
    assert!(diff <= 1e-5 * 1.5, "NK vs DR: {diff:e}");
    for (x, u) in model.reference().iter().zip(&sol.displacements) {
        assert!((x + u).coords.norm() <= skull.radius * (1.0 + 1e-12));
    }
}

/// The reported error bound holds against a solution converged 100× tighter, with contact
/// active: `|u_tol − u*| ≤ err_tol` where `u*` is known to `err_tight ≪ err_tol`.
#[test]
fn error_estimate_bounds_the_true_error_with_contact() {
    let (model, loads, mut skull) = sphere_case();
    for tol in [1e-3, 1e-4] {
        let loose =
            nk(tol).solve(bs_dr::Problem::new(&model, &loads, &mut skull, &mut |_| {})).unwrap();
        let tight = nk(tol / 100.0)
            .solve(bs_dr::Problem::new(&model, &loads, &mut skull, &mut |_| {}))
            .unwrap();
        assert!(loose.report.contact.nodes_in_contact > 0);
        let true_error = max_diff(&loose.displacements, &tight.displacements);
        assert!(
            true_error <= loose.report.err + tight.report.err,
            "tol {tol}: true error {true_error:e} above the estimate {:e}",
            loose.report.err
        );
        assert!(loose.report.err <= loose.report.tolerance);
    }
}

#[test]
fn bit_identical_for_1_and_2_threads() {
    let (model, loads, _) = sphere_case();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
            let (_, _, mut skull) = sphere_case();
            nk(1e-6).solve(bs_dr::Problem::new(&model, &loads, &mut skull, &mut |_| {})).unwrap()
        })
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.report.steps, b.report.steps);
    for (x, y) in a.displacements.iter().zip(&b.displacements) {
        for c in 0..3 {
            assert_eq!(x[c].to_bits(), y[c].to_bits());
        }
    }
}

/// A contact that can only enforce (no projection): the linearising solver refuses it with
/// a typed error instead of ignoring the constraint.
struct EnforceOnly(Vec<usize>);

impl Contact for EnforceOnly {
    fn enforce(&mut self, _positions: &mut [Point3<f64>]) -> ContactReport {
        ContactReport::default()
    }

    fn nodes(&self) -> &[usize] {
        &self.0
    }
}

#[test]
fn guards_are_typed_errors() {
    let material = Material::neo_hookean(3000.0, 0.45).unwrap();
    let (mesh, model) = cube_model(Tech::T4, 3, 1.0, 0.2, material);
    // A contact without projection.
    let loads = clamp_and_push(&mesh, 1.0, 0.1);
    let err = nk(1e-6)
        .solve(bs_dr::Problem::new(&model, &loads, &mut EnforceOnly(vec![1, 2]), &mut |_| {}))
        .unwrap_err();
    assert!(matches!(err, SolveError::Unsupported { .. }), "{err}");
    // Too few iterations, no fallback: the load not carried, with the budget named.
    let few = NewtonKrylov::new(NewtonKrylovParams {
        tolerance: 1e-12,
        max_iterations: 1,
        continuation: ContinuationParams { fallback: false, ..Default::default() },
        ..Default::default()
    });
    let err =
        few.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap_err();
    assert!(
        matches!(
            err,
            SolveError::LoadNotCarried {
                reached: 0.0,
                cause: LoadFailure::Exhausted { iterations: 1 },
                fallback: None,
                ..
            }
        ),
        "{err}"
    );
    // With the fallback, Dynamic Relaxation from the last converged state (here the
    // reference) carries the load: the same equilibrium as an unlimited solve.
    let few = NewtonKrylov::new(NewtonKrylovParams {
        tolerance: 1e-6,
        max_iterations: 1,
        ..Default::default()
    });
    let fell_back =
        few.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
    let full =
        nk(1e-6).solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap();
    let diff = fell_back
        .displacements
        .iter()
        .zip(&full.displacements)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(diff < 1e-4, "{diff}");
    // Crushing the block beyond its height inverts elements.
    let crush = clamp_and_push(&mesh, 1.0, 1.2);
    let err = nk(1e-6)
        .solve(bs_dr::Problem::new(&model, &crush, &mut NoContact, &mut |_| {}))
        .unwrap_err();
    assert!(matches!(err, SolveError::ElementInverted { .. }), "{err}");
    // Invalid parameters.
    let bad = NewtonKrylov::new(NewtonKrylovParams { forcing_max: 1.5, ..Default::default() });
    let err =
        bad.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |_| {})).unwrap_err();
    assert!(matches!(err, SolveError::InvalidParams { name: "forcing_max", .. }), "{err}");
}

/// A handler whose `enforce` disagrees with its exact `project`, as a search over per-node
/// candidate lists can after a large deformation: it moves the first contact node 5 units
/// along x.
struct WrongEnforce(Planes);

impl Contact for WrongEnforce {
    fn enforce(&mut self, positions: &mut [Point3<f64>]) -> ContactReport {
        let report = self.0.enforce(positions);
        positions[self.0.nodes[0]].x += 5.0;
        report
    }

    fn nodes(&self) -> &[usize] {
        self.0.nodes()
    }

    fn project(&mut self, k: usize, p: &Point3<f64>) -> Option<ContactProjection> {
        self.0.project(k, p)
    }
}

#[test]
fn the_converged_answer_is_corrected_by_the_exact_projection_not_by_enforce() {
    // The floor test's block: the answer may differ from the honest handler's only by
    // rounding (on the MNI152 demo a wrong `enforce` had moved a node 8.7 mm and inverted
    // elements of a converged answer).
    let (_, model, loads, bottom) = block_on_floor();
    let floor = |nodes: Vec<usize>| Planes {
        planes: vec![(-Vector3::z(), 0.0)],
        nodes,
        projected_on_edge: 0,
    };
    let honest = nk(1e-10)
        .solve(bs_dr::Problem::new(&model, &loads, &mut floor(bottom.clone()), &mut |_| {}))
        .unwrap();
    let mut wrong = WrongEnforce(floor(bottom));
    let sol =
        nk(1e-10).solve(bs_dr::Problem::new(&model, &loads, &mut wrong, &mut |_| {})).unwrap();
    let diff = max_diff(&sol.displacements, &honest.displacements);
    assert!(diff <= 1e-12, "{diff:e}");
    assert_eq!(sol.report.contact.nodes_in_contact, honest.report.contact.nodes_in_contact);
}

#[test]
fn a_budget_spent_while_loading_ends_at_a_converged_fraction_of_the_load() {
    // 60 % of the cube's height pushed in: the first load step is cut short by the elements
    // (at 78.6 % of the push). With a budget of 8 iterations and 6 per level, the level
    // used to load on to the full push at iteration 8 and end with nothing converged ("0 of
    // 0.6"); with one level's budget left it ends at the load it has applied and
    // equilibrates there.
    let material = Material::neo_hookean(3000.0, 0.45).unwrap();
    let (mesh, model) = cube_model(Tech::T4, 3, 1.0, 0.2, material);
    let loads = clamp_and_push(&mesh, 1.0, 0.6);
    let continuation =
        ContinuationParams { fallback: false, level_iterations: 6, ..Default::default() };
    let few = NewtonKrylov::new(NewtonKrylovParams {
        tolerance: 1e-6,
        max_iterations: 8,
        continuation,
        ..Default::default()
    });
    let mut applied = Vec::new();
    let err = few.solve(bs_dr::Problem::new(&model, &loads, &mut NoContact, &mut |p| {
        applied.push(p.load_factor)
    }));
    let first = applied[0];
    assert!(first > 0.5 && first < 1.0, "the first load step is cut short: {first}");
    match err {
        Err(SolveError::LoadNotCarried {
            reached, cause: LoadFailure::Exhausted { .. }, ..
        }) => {
            assert_eq!(reached, first, "ends at the load the first step applied");
        }
        other => panic!("{:?}", other.map(|s| s.report.steps)),
    }
}
