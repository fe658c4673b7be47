//! The cases against CalculiX: DR and Newton–Krylov with kinematic contact against the stored
//! references, without contact, held, and without a skull.

use super::row::{Row, load, solve};
use crate::calculix::{Reference, field, read_partial, read_reference};
use crate::study::{ContactChoice, Outcome, Variant, difference};
use crate::util::root;
use bs_mesh::{TriSurface, Vector3};
use bs_scene::Prepared;
use bs_scene::scene::{ElementChoice, SolverKind};

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
pub(super) fn calculix(add: &mut dyn FnMut(Row)) -> Result<(), String> {
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
pub(super) fn calculix_gravity(add: &mut dyn FnMut(Row)) -> Result<(), String> {
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
pub(super) fn calculix_cases(add: &mut dyn FnMut(Row), cases: &[&str]) -> Result<(), String> {
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
pub(super) fn calculix_without_contact_case(
    add: &mut dyn FnMut(Row),
    case: &str,
) -> Result<(), String> {
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
pub(super) fn calculix_held(add: &mut dyn FnMut(Row)) -> Result<(), String> {
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
