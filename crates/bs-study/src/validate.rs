//! `cargo xtask validate`: every reference case, one table (case, quantity, value,
//! tolerance, pass), written to `docs/validation.md`; non-zero exit if any case fails.
//!
//! Cases:
//! * homogeneous closed forms (uniaxial compression, simple shear) for T4, T4ANP and H8;
//! * a confined column under its own weight, dry and half submerged, against its closed
//!   form on T4ANP and H8 at three refinements;
//! * Dynamic Relaxation against Newton on the same mesh;
//! * every contact handler against brute force, as closest-point queries on the property
//!   surfaces and as whole contact solves;
//! * DR + kinematic contact against the stored CalculiX references (`cargo xtask reference`).
//!
//! Every tolerance is derived from the physics or the numerics of the case (documented next
//! to it), never from what the code happens to produce. The quick cases run in `cargo test`;
//! the whole set runs optimised (`cargo xtask validate` re-runs itself in release).

use std::fmt::Write as _;
use std::sync::Arc;

use crate::calculix::{Reference, field, read_partial, read_reference};
use crate::study::{ContactChoice, Outcome, Variant, difference};
use crate::util::{escape_cell, replace_block, root};
use bs_contact::shapes::{self, Rng};
use bs_contact::{BruteForce, ClosestPoint, Handler, MasterSurface, PaperParams};
use bs_mesh::{Point3, TriSurface, Vector3};
use bs_scene::Prepared;
use bs_scene::scene::{Algorithm, ElementChoice, SolverKind};

/// One line of the validation table.
#[derive(Debug, Clone)]
pub struct Row {
    /// Group and case, e.g. `closed form / uniaxial t4`.
    pub case: String,
    /// What is measured.
    pub quantity: String,
    /// Measured value.
    pub value: f64,
    /// Largest acceptable value.
    pub tolerance: f64,
    /// Unit of value and tolerance.
    pub unit: &'static str,
}

impl Row {
    /// Whether the value is within the tolerance (NaN never passes).
    pub fn pass(&self) -> bool {
        self.value <= self.tolerance
    }
}

/// Which cases to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// The cases that take seconds in a debug build (`cargo test`).
    Quick,
    /// Everything (release).
    Full,
}

fn load(rel: &str) -> Result<Prepared, String> {
    Prepared::load(&root().join(rel)).map_err(|e| format!("{rel}: {e}"))
}

fn solve(p: &Prepared, v: &Variant, what: &str) -> Result<Outcome, String> {
    v.solve(p).map_err(|e| format!("{what}: {e}"))
}

/// One row as `validate` prints it while measuring.
fn print_row(r: &Row) {
    println!(
        "{:<46} {:<40} {:>11.3e} {:>10.1e} {:<3} {}",
        r.case,
        r.quantity,
        r.value,
        r.tolerance,
        r.unit,
        if r.pass() { "pass" } else { "FAIL" }
    );
}

/// Runs the cases of `scope`, printing each row as it is measured.
pub fn run(scope: Scope) -> Result<Vec<Row>, String> {
    let mut rows = Vec::new();
    let mut add = |r: Row| {
        print_row(&r);
        rows.push(r);
    };
    closed_forms(&mut add)?;
    gravity_column(&mut add, scope)?;
    dr_vs_newton(&mut add)?;
    handler_queries(&mut add)?;
    if scope == Scope::Full {
        paper_40mm(&mut add)?;
        handler_solves(&mut add)?;
        calculix(&mut add)?;
        determinism(&mut add)?;
    }
    Ok(rows)
}

/// The bundled MNI152 scene solved on one thread and on two: the displacements must be
/// bit-identical (every parallel sum gathers in a fixed order).
fn determinism(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    let p = load("fixtures/mni152/scene.toml")?;
    let on = |threads: usize| -> Result<Outcome, String> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| e.to_string())?;
        pool.install(|| solve(&p, &Variant::default(), "determinism"))
    };
    let (one, two) = (on(1)?, on(2)?);
    let differing = one
        .displacements
        .iter()
        .zip(&two.displacements)
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.to_bits() != y.to_bits()))
        .count();
    add(Row {
        case: "determinism / mni152 newton-krylov".into(),
        quantity: "nodes not bit-identical, 1 vs 2 threads".into(),
        value: differing as f64,
        tolerance: 0.0,
        unit: "",
    });
    Ok(())
}

/// Uniaxial compression (10 %, symmetry planes, lateral faces free) and simple shear
/// (γ = 0.2, every boundary node prescribed) of the unit cube: the exact fields are
/// homogeneous, which linear tetrahedra and mean-strain hexahedra represent exactly, so the
/// only error is the solver's. Tolerance: 1e-6 of the largest displacement, three orders
/// above the scenes' DR tolerance (1e-10 mm on 0.1–0.2 mm) and far below any formulation
/// error (a wrong stress term shows at 1e-3 and above).
fn closed_forms(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    let (e, nu) = (3000.0, 0.3);
    let (mu, kappa) = (e / (2.0 * (1.0 + nu)), e / (3.0 * (1.0 - 2.0 * nu)));
    let lambda = 0.9;
    let l = bs_material::closed_form::neo_hookean_uniaxial_lateral_stretch(lambda, mu, kappa)
        .ok_or("no lateral stretch")?;
    let gamma = 0.2;
    for (element, solver) in ["t4", "t4anp", "h8"]
        .into_iter()
        .flat_map(|e| [(e, SolverKind::NewtonKrylov), (e, SolverKind::Dr)])
    {
        let v = Variant { solver: Some(solver), ..Variant::default() };
        let p = load(&format!("fixtures/cube/uniaxial-{element}.toml"))?;
        let o = solve(&p, &v, "uniaxial")?;
        let worst = p
            .mesh
            .nodes
            .iter()
            .zip(&o.displacements)
            .map(|(x, u)| {
                (u - Vector3::new((l - 1.0) * x.x, (l - 1.0) * x.y, (lambda - 1.0) * x.z)).amax()
            })
            .fold(0.0, f64::max);
        add(Row {
            case: format!("closed form / uniaxial {element} {}", solver.name()),
            quantity: "max nodal error / max |u|".into(),
            value: worst / (1.0 - lambda),
            tolerance: 1e-6,
            unit: "",
        });
        let p = load(&format!("fixtures/cube/shear-{element}.toml"))?;
        let o = solve(&p, &v, "shear")?;
        let worst = p
            .mesh
            .nodes
            .iter()
            .zip(&o.displacements)
            .map(|(x, u)| (u - Vector3::new(gamma * x.y, 0.0, 0.0)).amax())
            .fold(0.0, f64::max);
        add(Row {
            case: format!("closed form / shear {element} {}", solver.name()),
            quantity: "max nodal error / max |u|".into(),
            value: worst / gamma,
            tolerance: 1e-6,
            unit: "",
        });
    }
    Ok(())
}

/// The confined column of `fixtures/column` (20 × 20 × 80 mm, rollers on its sides and
/// base) under its own weight, dry and with its lower half in cerebrospinal fluid, against
/// `confined_column_displacement` (the settlement 2.85 mm dry, 2.16 mm half submerged).
/// Rows: the largest nodal error of `u_z` relative to the settlement on 16 layers (T4ANP and
/// H8; Newton–Krylov, and DR on H8 in the full scope), and its ratio from 8 to 16 layers.
/// Tolerances: on 16 layers 1 % (measured: T4ANP 0.43 % dry, 0.57 % half submerged; H8
/// 7e-6, second order); the ratio ≤ 0.5, a discretisation that converges (second order
/// gives 0.25: H8 0.250, T4ANP 0.27–0.29).
fn gravity_column(add: &mut dyn FnMut(Row), scope: Scope) -> Result<(), String> {
    use bs_material::closed_form::confined_column_displacement;
    let path = root().join("fixtures/column/scene.toml");
    let base = bs_scene::scene::Scene::load(&path).map_err(|e| e.to_string())?;
    let gravity = base.gravity.clone().ok_or("fixtures/column/scene.toml has no [gravity]")?;
    let fluid = gravity.fluid.ok_or("fixtures/column/scene.toml has no fluid")?;
    let region = &base.regions[0].material;
    let law = bs_scene::compose::material(region)?;
    let (rho, g) = (region.density_or_default(), gravity.acceleration * 1e-3);
    let height = 80.0;
    for (element, file) in [(ElementChoice::T4anp, "t4"), (ElementChoice::H8, "h8")] {
        for submerged in [false, true] {
            let weight = |z: f64| {
                let wet = submerged && z < fluid.level[2];
                if wet { (rho - fluid.density) * g } else { rho * g }
            };
            let mut errors = Vec::new();
            let solvers: &[SolverKind] = if scope == Scope::Full && element == ElementChoice::H8 {
                &[SolverKind::NewtonKrylov, SolverKind::Dr]
            } else {
                &[SolverKind::NewtonKrylov]
            };
            for layers in [8, 16] {
                let mut scene = base.clone();
                scene.mesh.file = path.with_file_name(format!("column-{file}-{layers}.inp"));
                scene.mesh.element = Some(element);
                if !submerged && let Some(g) = scene.gravity.as_mut() {
                    g.fluid = None;
                }
                let p = Prepared::from_scene(&path, scene).map_err(|e| e.to_string())?;
                let z: Vec<f64> = p.mesh.nodes.iter().map(|x| x.z).collect();
                let exact = confined_column_displacement(&law, height, &weight, 0.0, &z)
                    .ok_or("no closed form")?;
                let settlement = -exact.iter().copied().fold(0.0, f64::min);
                for &solver in if layers == 16 { solvers } else { &solvers[..1] } {
                    let v = Variant { solver: Some(solver), ..Variant::default() };
                    let o = solve(&p, &v, "gravity column")?;
                    let err = o
                        .displacements
                        .iter()
                        .zip(&exact)
                        .map(|(u, e)| (u.z - e).abs())
                        .fold(0.0, f64::max);
                    if solver == SolverKind::NewtonKrylov {
                        errors.push(err);
                    }
                    if layers == 16 {
                        let wet = if submerged { "half submerged" } else { "dry" };
                        add(Row {
                            case: format!(
                                "closed form / column {wet} {} {}",
                                element.name(),
                                solver.name()
                            ),
                            quantity: "max |u_z error| / settlement, 16 layers".into(),
                            value: err / settlement,
                            tolerance: 1e-2,
                            unit: "",
                        });
                    }
                }
            }
            let wet = if submerged { "half submerged" } else { "dry" };
            add(Row {
                case: format!("closed form / column {wet} {}", element.name()),
                quantity: "error ratio, 16 against 8 layers".into(),
                value: errors[1] / errors[0],
                tolerance: 0.5,
                unit: "",
            });
        }
    }
    Ok(())
}

/// DR and Newton–Krylov against Newton on the coarse ellipsoid (T4, its 10 mm push, no
/// skull: Newton needs no contact). All solve the same discrete equations; DR and
/// Newton–Krylov stop when their error estimate is below 1e-5 mm, Newton at 1e-10 of the
/// load. Tolerance: 10× the tolerance, because DR's estimate extrapolates the slowest mode
/// and may under-read by a small factor.
fn dr_vs_newton(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    let p = load("fixtures/ellipsoid/scene.toml")?;
    let tol = 1e-5;
    let base = Variant {
        element: Some(ElementChoice::T4),
        contact: Some(ContactChoice::Off),
        tolerance: Some(tol),
        ..Variant::default()
    };
    let newton =
        solve(&p, &Variant { solver: Some(SolverKind::Newton), ..base.clone() }, "Newton")?;
    for solver in [SolverKind::Dr, SolverKind::NewtonKrylov] {
        let o = solve(&p, &Variant { solver: Some(solver), ..base.clone() }, solver.name())?;
        let (_, max) = difference(&o.displacements, &newton.displacements, None);
        add(Row {
            case: format!("{} vs Newton / ellipsoid coarse t4", solver.name()),
            quantity: "max nodal difference".into(),
            value: max,
            tolerance: 10.0 * tol,
            unit: "mm",
        });
    }
    Ok(())
}

/// The paper's first experiment by the paper's method: the hexahedral ellipsoid pushed
/// 40 mm with skull contact (`fixtures/ellipsoid/scene-40mm-dr.toml`), Dynamic Relaxation
/// against Newton–Krylov on the same scene. The paper's DR agreed with LS-Dyna to 0.12 mm
/// mean; two of our solvers converged to 1e-3 mm on the same discrete problem must agree at
/// least as well (the max allows 1 mm for a different contact equilibrium on a few nodes).
fn paper_40mm(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    let p = load("fixtures/ellipsoid/scene-40mm-dr.toml")?;
    let dr = solve(&p, &Variant::default(), "DR")?;
    let nk = Variant {
        solver: Some(SolverKind::NewtonKrylov),
        max_steps: Some(1000),
        ..Variant::default()
    };
    let nk = solve(&p, &nk, "Newton-Krylov")?;
    let (mean, max) = difference(&dr.displacements, &nk.displacements, None);
    let case = "paper 40 mm / ellipsoid hex DR vs Newton-Krylov";
    for (quantity, value, tolerance) in
        [("mean nodal difference", mean, 0.12), ("max nodal difference", max, 1.0)]
    {
        add(Row { case: case.into(), quantity: quantity.into(), value, tolerance, unit: "mm" });
    }
    Ok(())
}

/// Property surfaces of the contact tests: smooth, refined, non-convex and sharp-cornered.
fn property_surfaces() -> Vec<(&'static str, TriSurface)> {
    let radii = Vector3::new(1.0, 0.8, 0.6);
    let coarse = shapes::ellipsoid(120, radii);
    vec![
        ("ellipsoid-120x4", shapes::refine(&coarse, |p| shapes::onto_ellipsoid(p, radii))),
        ("bumpy", shapes::bumpy_sphere(500, 10, 0.25, 7)),
        ("convex-60", shapes::random_convex(60, 5)),
    ]
}

/// Every handler's closest point against brute force on 3000 random queries within the
/// handler's reach of each property surface (inside and outside). Tolerances: distances
/// agree to 1e-9 of the model size (different formulas for the same point differ by
/// rounding, ~1e-15), and no inside/outside verdict may differ.
fn handler_queries(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    for (name, s) in property_surfaces() {
        let m = Arc::new(MasterSurface::new(&s).map_err(|e| e.to_string())?);
        let brute = BruteForce::from_master(m.clone());
        for alg in [
            bs_contact::Algorithm::Paper,
            bs_contact::Algorithm::Coherent,
            bs_contact::Algorithm::Parry,
        ] {
            let mut h = Handler::new(alg, &s, PaperParams::default()).map_err(|e| e.to_string())?;
            let reach = h.reach().min(2.0 * m.max_edge());
            let mut rng = Rng::new(7);
            let (mut worst, mut verdicts) = (0.0f64, 0usize);
            for i in 0..3000 {
                let q = surface_point(&s, &mut rng) + rng.direction() * rng.range(0.0, reach);
                let b = brute.project(&q);
                match h.closest(i % 7, &q) {
                    Some(p) => {
                        worst = worst.max((p.signed_distance - b.signed_distance).abs());
                        verdicts += usize::from(p.outside != b.outside);
                    }
                    // "No correction needed": wrong only if brute force says outside.
                    None => verdicts += usize::from(b.outside),
                }
            }
            let label = format!("{alg:?}").to_lowercase();
            add(Row {
                case: format!("contact query / {label} on {name}"),
                quantity: "max |distance − brute force| / size".into(),
                value: worst / m.size(),
                tolerance: 1e-9,
                unit: "",
            });
            add(Row {
                case: format!("contact query / {label} on {name}"),
                quantity: "inside/outside verdicts differing".into(),
                value: verdicts as f64,
                tolerance: 0.0,
                unit: "",
            });
        }
    }
    Ok(())
}

/// A uniformly random point of a random triangle.
fn surface_point(s: &TriSurface, rng: &mut Rng) -> Point3<f64> {
    let t = s.triangles[(rng.next_u64() % s.triangles.len() as u64) as usize];
    let (mut u, mut v) = (rng.uniform(), rng.uniform());
    if u + v > 1.0 {
        u = 1.0 - u;
        v = 1.0 - v;
    }
    let a = s.vertices[t[0]];
    a + (s.vertices[t[1]] - a) * u + (s.vertices[t[2]] - a) * v
}

/// Whole DR + contact solves of the coarse ellipsoid (T4ANP, 10 mm push) with each handler
/// in DR's per-step enforcement, and the Newton–Krylov solve, against DR with the
/// brute-force handler. Each converged solution is within its tolerance of the same discrete
/// equilibrium, so two differ by at most twice the tolerance (×5 for DR's estimate's
/// extrapolation, as above). The result must also leave no node outside the skull by more
/// than the tolerance.
fn handler_solves(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    let p = load("fixtures/ellipsoid/scene.toml")?;
    let tol = 1e-4;
    let with = |a: Algorithm, solver: SolverKind| Variant {
        contact: Some(ContactChoice::Handler(a)),
        tolerance: Some(tol),
        solver: Some(solver),
        ..Variant::default()
    };
    let brute = solve(&p, &with(Algorithm::BruteForce, SolverKind::Dr), "brute force")?;
    let runs = [Algorithm::Paper, Algorithm::Coherent, Algorithm::Parry]
        .map(|a| (a, SolverKind::Dr))
        .into_iter()
        .chain([(Algorithm::Coherent, SolverKind::NewtonKrylov)]);
    for (a, solver) in runs {
        let o = solve(&p, &with(a, solver), a.name())?;
        let (_, max) = difference(&o.displacements, &brute.displacements, None);
        let case = format!("contact solve / {} {} vs dr brute-force", solver.name(), a.name());
        add(Row {
            case: case.clone(),
            quantity: "max nodal difference".into(),
            value: max,
            tolerance: 10.0 * tol,
            unit: "mm",
        });
        add(Row {
            case,
            quantity: "max penetration of the result".into(),
            value: o.max_penetration_after,
            tolerance: tol,
            unit: "mm",
        });
    }
    Ok(())
}

/// The DR tolerance of the runs compared with CalculiX (mm).
pub const CCX_DR_TOLERANCE: f64 = 1e-4;

/// How far two valid enforcements of the same faceted rigid surface may place a contact
/// node: CalculiX's node-to-surface springs act along face normals of the face a node
/// projects onto, the kinematic contact moves nodes to the exact closest point (onto edges
/// and vertices too), so across an edge of length L with dihedral angle θ the two constraint
/// surfaces may differ by up to the facet sagitta L·θ/8. Mean and max over the skull edges.
pub fn facet_allowance(skull: &TriSurface) -> Result<(f64, f64), String> {
    let topo = skull.topology().map_err(|e| e.to_string())?;
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for e in &topo.edges {
        let [Some(f), Some(g)] = e.faces else { continue };
        let (a, b) = (skull.area_normal(f).normalize(), skull.area_normal(g).normalize());
        let theta = a.dot(&b).clamp(-1.0, 1.0).acos();
        let l = (skull.vertices[e.nodes[0]] - skull.vertices[e.nodes[1]]).norm();
        let s = l * theta / 8.0;
        sum += s;
        max = max.max(s);
        n += 1;
    }
    Ok((if n == 0 { 0.0 } else { sum / n as f64 }, max))
}

/// Newton–Krylov and DR, both with the kinematic contact (T4 on the reference's own mesh:
/// CalculiX's C3D4 is the same element), against CalculiX with penalty slope K = 10. The tolerance adds the sources of
/// legitimate difference, each from the physics or the numerics, none from our result:
/// * the reference's penalty sensitivity |u(K=1) − u(K=10)| (the penalty error falls as 1/K,
///   so K = 10 is within a ninth of that of the exact-contact limit);
/// * the DR tolerance;
/// * the facet allowance of the skull ([`facet_allowance`]), mean for the mean, max for the
///   max.
///
/// The targets (0.03 mm mean, 0.3 mm max) cap it from above.
fn calculix(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    calculix_gravity(add)?;
    calculix_without_contact(add)?;
    calculix_cases(add, &["sphere-shell", "ellipsoid", "mni152", "mni152-regions"])
}

/// Gravity with skull contact against CalculiX (`*DLOAD GRAV`): the coarse ellipsoid's
/// push with the fluid drained above y = 50 mm (`fixtures/ellipsoid/scene-gravity.toml`,
/// reference `ccx-gravity-k10`, small sliding in 1.25 % increments). Tolerances: the
/// issue's 0.05 mm mean (the contact cases' penalty and facet allowances are 0.01–0.03 mm
/// here), and the contact cases' 0.3 mm cap on the max. Skipped, saying so, when the stored
/// run did not reach the whole load.
fn calculix_gravity(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    let dir = root().join("fixtures/ellipsoid/reference");
    let label = "CalculiX / ellipsoid gravity";
    let Some(k10) = read_reference(&dir, "ccx-gravity-k10")? else {
        println!(
            "{label}: no stored reference (cargo xtask reference --case ellipsoid/ccx-gravity)"
        );
        return Ok(());
    };
    if k10.meta["converged"] != serde_json::Value::Bool(true) {
        println!(
            "{label}: CalculiX K=10 stopped at {:.3} of the load; no comparison",
            k10.meta["load_fraction_reached"].as_f64().unwrap_or(f64::NAN)
        );
        return Ok(());
    }
    let p = load("fixtures/ellipsoid/scene-gravity.toml")?;
    let u10 = field(&p, &k10, label)?;
    for solver in [SolverKind::NewtonKrylov, SolverKind::Dr] {
        let (o, mean, max) = against_ccx(&p, solver, None, &u10, label)?;
        let case = format!("{label} / {} t4", solver.name());
        contact_rows(add, &case, "u_ccx(K=10)", (mean, max), (PARTIAL_MEAN, PARTIAL_MAX), &o);
    }
    Ok(())
}

/// [`calculix`]'s comparison for the named fixtures (`cargo xtask validate --calculix CASE`
/// runs one alone).
fn calculix_cases(add: &mut dyn FnMut(Row), cases: &[&str]) -> Result<(), String> {
    for &case in cases {
        let dir = root().join("fixtures").join(case).join("reference");
        let label = format!("CalculiX / {case}");
        let Some(k10) = read_reference(&dir, "ccx-k10")? else {
            println!("{case}: no stored CalculiX reference (run `cargo xtask reference`)");
            continue;
        };
        if k10.meta["converged"] != serde_json::Value::Bool(true) {
            // A run that stopped short: its last converged increment, if stored, is a
            // reference at that fraction of the load.
            // The softer penalty too, where it stopped (its own fraction of the load).
            if let Some(k1) = read_reference(&dir, "ccx-k1")?
                && k1.meta["converged"] != serde_json::Value::Bool(true)
                && let Some(partial) = read_partial(&dir, &k1)?
            {
                calculix_partial(add, case, &partial, "K=1")?;
            }
            match read_partial(&dir, &k10)? {
                Some(partial) => calculix_partial(add, case, &partial, "K=10")?,
                None if k10.displacements.is_empty() => println!(
                    "{label}: CalculiX K=10 did not converge (reached {:.3} of the load); no \
                     comparison",
                    k10.meta["load_fraction_reached"].as_f64().unwrap_or(f64::NAN)
                ),
                None => return Err(format!("{label}: the stored K=10 run did not converge")),
            }
            continue;
        }
        let Some(k1) = read_reference(&dir, "ccx-k1")? else {
            println!("{case}: no stored CalculiX K=1 reference (run `cargo xtask reference`)");
            continue;
        };
        let p = load(&format!("fixtures/{case}/scene.toml"))?;
        let u10 = field(&p, &k10, &label)?;
        let u1 = field(&p, &k1, &label)?;
        let (sens_mean, sens_max) = difference(&u1, &u10, None);
        let skull = p.skull.as_ref().ok_or("the scene has no skull")?;
        let (facet_mean, facet_max) = facet_allowance(skull)?;
        for solver in [SolverKind::NewtonKrylov, SolverKind::Dr] {
            let (o, mean, max) = against_ccx(&p, solver, None, &u10, &label)?;
            println!(
                "{label} {}: penalty sensitivity mean {sens_mean:.2e} max {sens_max:.2e} mm; \
                 facet allowance mean {facet_mean:.2e} max {facet_max:.2e} mm; {} iterations \
                 {:.1} s; ccx {:.1} s",
                solver.name(),
                o.steps,
                o.solve_seconds,
                k10.meta["wall_seconds"].as_f64().unwrap_or(f64::NAN)
            );
            let case = format!("{label} / {} t4", solver.name());
            let tolerances = (
                (sens_mean + CCX_DR_TOLERANCE + facet_mean).min(0.03),
                (sens_max + CCX_DR_TOLERANCE + facet_max).min(0.3),
            );
            contact_rows(add, &case, "u_ccx(K=10)", (mean, max), tolerances, &o);
        }
    }
    Ok(())
}

/// `solver` (T4, at the DR tolerance of the CalculiX comparisons, the push scaled by
/// `load_factor`) against the CalculiX field `u_ccx`: the outcome, the mean and max nodal
/// difference; where they differ most is printed.
fn against_ccx(
    p: &Prepared,
    solver: SolverKind,
    load_factor: Option<f64>,
    u_ccx: &[Vector3<f64>],
    label: &str,
) -> Result<(Outcome, f64, f64), String> {
    let v = Variant {
        element: Some(ElementChoice::T4),
        tolerance: Some(CCX_DR_TOLERANCE),
        solver: Some(solver),
        load_factor,
        ..Variant::default()
    };
    let o = solve(p, &v, label)?;
    let (mean, max) = difference(&o.displacements, u_ccx, None);
    println!("{label} {}: {}", solver.name(), worst_node(p, &o.displacements, u_ccx));
    Ok((o, mean, max))
}

/// The three rows of a contact solve against CalculiX: mean and max nodal difference to
/// `reference` with their tolerances, and the penetration of the result.
fn contact_rows(
    add: &mut dyn FnMut(Row),
    case: &str,
    reference: &str,
    (mean, max): (f64, f64),
    (mean_tolerance, max_tolerance): (f64, f64),
    o: &Outcome,
) {
    let row = |quantity: String, value: f64, tolerance: f64| Row {
        case: case.to_string(),
        quantity,
        value,
        tolerance,
        unit: "mm",
    };
    add(row(format!("mean nodal |u − {reference}|"), mean, mean_tolerance));
    add(row(format!("max nodal |u − {reference}|"), max, max_tolerance));
    add(row("max penetration of the result".into(), o.max_penetration_after, CCX_DR_TOLERANCE));
}

/// Tolerances against a CalculiX run that stopped short of the full load (mm): the mean is
/// issue 26's target for the patient-like case; the max is the cap of the other contact
/// cases. The penalty's own effect cannot be measured (the K = 1 run stopped at another
/// fraction of the load), so no tighter bound is derived.
const PARTIAL_MEAN: f64 = 0.05;
const PARTIAL_MAX: f64 = 0.3;

/// Newton–Krylov and DR (T4) at the fraction of the load a stopped CalculiX run reached,
/// against its last converged increment: frictionless contact and hyperelastic materials
/// make the static state independent of the loading path, so the two are the same problem.
fn calculix_partial(
    add: &mut dyn FnMut(Row),
    case: &str,
    r: &Reference,
    slope: &str,
) -> Result<(), String> {
    let p = load(&format!("fixtures/{case}/scene.toml"))?;
    let fraction = r.meta["load_fraction_reached"].as_f64().ok_or("no load_fraction_reached")?;
    let label = format!("CalculiX {slope} / {case} at {:.1} % of the load", 100.0 * fraction);
    let u_ref = field(&p, r, &label)?;
    for solver in [SolverKind::NewtonKrylov, SolverKind::Dr] {
        let (o, mean, max) = against_ccx(&p, solver, Some(fraction), &u_ref, &label)?;
        println!(
            "{label} {}: {} iterations {:.1} s; ccx stopped after {:.0} s",
            solver.name(),
            o.steps,
            o.solve_seconds,
            r.meta["wall_seconds"].as_f64().unwrap_or(f64::NAN)
        );
        let case = format!("{label} / {} t4", solver.name());
        let reference = format!("u_ccx({slope}, {fraction:.3})");
        contact_rows(add, &case, &reference, (mean, max), (PARTIAL_MEAN, PARTIAL_MAX), &o);
    }
    Ok(())
}

/// Where `a` and `b` differ most: the node id, its position and the regions of its elements.
fn worst_node(p: &Prepared, a: &[Vector3<f64>], b: &[Vector3<f64>]) -> String {
    let d = |i: usize| (a[i] - b[i]).norm();
    let worst = (0..a.len().min(b.len())).max_by(|&x, &y| d(x).total_cmp(&d(y))).unwrap_or(0);
    let at = p.mesh.nodes[worst];
    let regions: std::collections::BTreeSet<&str> = p
        .mesh
        .elements
        .iter()
        .enumerate()
        .filter(|(_, el)| el.nodes().contains(&worst))
        .map(|(e, _)| p.scene.regions[p.region_of_element[e]].elset.as_str())
        .collect();
    format!(
        "max difference {:.3e} at node {} ({:.1}, {:.1}, {:.1}) in {}",
        d(worst),
        p.mesh.node_ids[worst],
        at.x,
        at.y,
        at.z,
        regions.into_iter().collect::<Vec<_>>().join(" | ")
    )
}

/// DR (T4, no skull) against CalculiX (C3D4, no skull) on the coarse ellipsoid's 10 mm
/// push: the same discrete equations, so this isolates material law, element and geometric
/// nonlinearity from the contact formulation. Tolerance: 10× the DR tolerance (as for DR vs
/// Newton) plus ccx's print precision (7 significant digits of the largest displacement
/// component).
fn calculix_without_contact(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    calculix_without_contact_case(add, "ellipsoid")?;
    calculix_without_contact_case(add, "mni152-regions")?;
    calculix_held(add)
}

/// [`calculix_without_contact`] for one fixture with a stored `ccx-nocontact` reference.
fn calculix_without_contact_case(add: &mut dyn FnMut(Row), case: &str) -> Result<(), String> {
    let label = format!("CalculiX no contact / {case}");
    calculix_no_skull(add, case, "scene.toml", "ccx-nocontact", &label, None)
}

/// Gravity, the craniotomy's push and the tumour's resection on the regions brain, its outer
/// boundary held beyond 50 mm of the craniotomy (`fixtures/mni152-regions/scene-held*.toml`).
/// At full weight (`ccx-held-dry`) both codes load every element alike, so the tolerance is
/// that of the same discrete equations (the no-contact rows'). With the fluid drained above
/// the craniotomy (`ccx-held`) the elements the level cuts are loaded differently (CalculiX
/// spreads an element's buoyancy as its weight, brainshift integrates the cut exactly): the
/// issue's 0.05 mm mean, and the 0.3 mm cap of the contact rows on the max.
fn calculix_held(add: &mut dyn FnMut(Row)) -> Result<(), String> {
    let (case, label) = ("mni152-regions", "CalculiX held / regions gravity + resection");
    calculix_no_skull(
        add,
        case,
        "scene-held-dry.toml",
        "ccx-held-dry",
        &format!("{label}, dry"),
        None,
    )?;
    let label = format!("{label}, CSF drained");
    calculix_no_skull(add, case, "scene-held.toml", "ccx-held", &label, Some((0.05, 0.3)))
}

/// T4 at tolerance 1e-5 against a stored CalculiX run of `scene` without a skull, within
/// `tolerance` (mean, max; default: the same discrete equations', 10× the solver's tolerance
/// plus ccx's print precision).
fn calculix_no_skull(
    add: &mut dyn FnMut(Row),
    case: &str,
    scene: &str,
    stem: &str,
    label: &str,
    tolerance: Option<(f64, f64)>,
) -> Result<(), String> {
    let dir = root().join("fixtures").join(case).join("reference");
    let Some(r) = read_reference(&dir, stem)? else {
        println!("{label}: no stored CalculiX run (cargo xtask reference --case {case}/{stem})");
        return Ok(());
    };
    if r.meta["converged"] != serde_json::Value::Bool(true) {
        return Err(format!("{label}: the stored CalculiX run {stem} did not converge"));
    }
    let p = load(&format!("fixtures/{case}/{scene}"))?;
    let label = label.to_string();
    let reference = field(&p, &r, &label)?;
    let tol = 1e-5;
    let v = Variant {
        element: Some(ElementChoice::T4),
        contact: Some(ContactChoice::Off),
        tolerance: Some(tol),
        ..Variant::default()
    };
    let o = solve(&p, &v, &label)?;
    let (mean, max) = difference(&o.displacements, &reference, None);
    println!("{label}: {}", worst_node(&p, &o.displacements, &reference));
    // ccx prints 7 significant digits: half a unit of the 7th digit of the largest value.
    let print = 5e-7 * reference.iter().map(|u| u.amax()).fold(0.0, f64::max);
    let (tol_mean, tol_max) = tolerance.unwrap_or((10.0 * tol + print, 10.0 * tol + print));
    add(Row {
        case: label.clone(),
        quantity: "mean nodal |u − u_ccx|".into(),
        value: mean,
        tolerance: tol_mean,
        unit: "mm",
    });
    add(Row {
        case: label,
        quantity: "max nodal |u − u_ccx|".into(),
        value: max,
        tolerance: tol_max,
        unit: "mm",
    });
    Ok(())
}

/// The table as Markdown.
pub fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| case | quantity | value | tolerance | unit | pass |\n|---|---|---:|---:|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3e} | {:.1e} | {} | {} |",
            escape_cell(&r.case),
            escape_cell(&r.quantity),
            r.value,
            r.tolerance,
            r.unit,
            if r.pass() { "pass" } else { "**FAIL**" }
        );
    }
    s
}

/// `cargo xtask validate [--quick]`: all cases (or the quick ones), the table written into
/// docs/validation.md between its markers (full run only); error if any case fails.
pub fn main(args: &[String]) -> Result<(), String> {
    let scope = match args {
        [] => Scope::Full,
        [q] if q == "--quick" => Scope::Quick,
        [flag, case] if flag == "--calculix" => {
            // One CalculiX case alone, printed, docs/validation.md untouched.
            let mut failed = 0;
            let mut print = |r: Row| {
                print_row(&r);
                failed += usize::from(!r.pass());
            };
            if case == "ellipsoid-gravity" {
                calculix_gravity(&mut print)?;
            } else if case == "regions-held" {
                calculix_held(&mut print)?;
            } else {
                calculix_without_contact_case(&mut print, case)?;
                calculix_cases(&mut print, &[case.as_str()])?;
            }
            return if failed == 0 { Ok(()) } else { Err(format!("{failed} case(s) failed")) };
        }
        _ => {
            return Err("usage: cargo xtask validate [--quick | --calculix CASE] (CASE: a \
                        fixture with stored references, ellipsoid-gravity or regions-held)"
                .into());
        }
    };
    let rows = run(scope)?;
    if scope == Scope::Quick {
        let failed = rows.iter().filter(|r| !r.pass()).count();
        println!("{} quick cases, {failed} failed", rows.len());
        return if failed == 0 { Ok(()) } else { Err(format!("{failed} case(s) failed")) };
    }
    let table = markdown(&rows);
    let path = root().join("docs/validation.md");
    replace_block(&path, "table", &table)?;
    let failed = rows.iter().filter(|r| !r.pass()).count();
    println!("{} cases, {failed} failed; table written to {}", rows.len(), path.display());
    if failed > 0 {
        return Err(format!("{failed} validation case(s) outside tolerance"));
    }
    Ok(())
}
