//! Verification of a result before it is written, by checks independent of the solver's own
//! stopping rule: no brain node outside the skull, every element with J > 0, and
//! equilibrium at the free nodes. A result that fails one is an error naming the worst node
//! or element, and nothing is written.

use nalgebra::Vector3;

use crate::compose::Composed;
pub use crate::error::VerifyError;
use crate::gap::exact_gaps;
use crate::prepare::Prepared;

/// Contact state of a result, measured exactly (parry's BVH and the exact point–triangle
/// projection, independent of the handler the solver used; once per solve).
#[derive(Debug, Clone, PartialEq)]
pub struct ContactState {
    /// Per node: 1 if the node is a slave within the tolerance of the skull, else 0.
    pub in_contact: Vec<f64>,
    /// Largest distance of any slave outside the skull (0 if none).
    pub max_penetration: f64,
    /// Slaves outside by more than the tolerance, and the worst one (node index, distance).
    pub outside: usize,
    /// The slave farthest outside beyond the tolerance.
    pub worst: Option<(usize, f64)>,
}

/// The contact state of displacements `u` with tolerance `tol` (no skull: nothing in
/// contact, nothing outside).
pub fn contact_state(p: &Prepared, c: &Composed, u: &[Vector3<f64>], tol: f64) -> ContactState {
    let mut st = ContactState {
        in_contact: vec![0.0; p.mesh.nodes.len()],
        max_penetration: 0.0,
        outside: 0,
        worst: None,
    };
    if let Some(exact) = &c.exact {
        let points = c.slaves.iter().map(|&i| p.mesh.nodes[i] + u[i]);
        for (row, &i) in exact_gaps(exact, points).iter().zip(&c.slaves) {
            if row.signed_distance <= tol {
                st.in_contact[i] = 1.0;
            }
            if row.outside {
                let d = -row.signed_distance;
                st.max_penetration = st.max_penetration.max(d);
                if d > tol {
                    st.outside += 1;
                    if st.worst.is_none_or(|(_, w)| d > w) {
                        st.worst = Some((i, d));
                    }
                }
            }
        }
    }
    st
}

/// The figures of a verified result (they go into report.json).
#[derive(Debug, Clone, PartialEq)]
pub struct Verification {
    /// Per node: 1 if the node is a slave within the tolerance of the skull, else 0.
    pub in_contact: Vec<f64>,
    /// Largest distance of any slave outside the skull (mesh length units).
    pub max_penetration_after: f64,
    /// Smallest element volume ratio J (> 0 in a verified result).
    pub min_jacobian: f64,
    /// Largest out-of-balance force at a free node out of contact, relative to the largest
    /// reaction force (prescribed and contact nodes).
    pub equilibrium_residual: f64,
    /// The bound `equilibrium_residual` met.
    pub equilibrium_bound: f64,
    /// Volume ratio and von Mises stress per element (what the result file shows).
    pub measures: bs_dr::ElementMeasures,
}

/// The largest relative out-of-balance force a result may keep at tolerance `tol` with
/// loads of size `load_scale` (both mesh length units): `10 tol / load_scale`, capped at 1.
///
/// A displacement error `δ` leaves a residual of about `k δ` at a node of stiffness `k`, and
/// the largest reaction is about `k u_max`, so a converged result keeps a relative residual
/// of order `tol / load_scale`. Measured on the contact fixtures (sphere-shell, ellipsoid,
/// mni152 coarse and default) with both solvers at tolerance 1e-3 mm, the ratio of the
/// residual to `tol / load_scale` lies between 0.001 (Newton–Krylov) and 0.26 (DR on
/// sphere-shell): the factor 10 leaves a margin of 38 over the worst, and a result whose
/// residual exceeds it did not converge to the tolerance, whatever the solver reported.
pub fn equilibrium_bound(tol: f64, load_scale: f64) -> f64 {
    (EQUILIBRIUM_FACTOR * tol / load_scale).min(1.0)
}

const EQUILIBRIUM_FACTOR: f64 = 10.0;

/// Verifies displacements `u` of a solve with tolerance `tol`: the exact contact state,
/// the smallest J and the equilibrium residual. A result that fails one check is an error
/// naming the worst node or element; such a result is never written.
pub fn verify(
    p: &Prepared,
    c: &Composed,
    u: &[Vector3<f64>],
    tol: f64,
) -> Result<Verification, VerifyError> {
    let st = contact_state(p, c, u, tol);
    if let Some((i, d)) = st.worst {
        return Err(VerifyError::OutsideSkull {
            count: st.outside,
            node_id: p.mesh.node_ids[i],
            distance: d,
            tolerance: tol,
        });
    }
    let measures = match c.model.element_measures(u) {
        Ok(m) => m,
        Err(bs_dr::SolveError::ElementInverted { element, jacobian, .. }) => {
            return Err(VerifyError::Inverted {
                element_id: p.mesh.element_ids[element],
                jacobian,
            });
        }
        Err(_) => {
            // Only a displacement field of the wrong length gets here: not a result.
            return Err(VerifyError::Inverted {
                element_id: p.mesh.element_ids.first().copied().unwrap_or(0),
                jacobian: f64::NAN,
            });
        }
    };
    let (min_jacobian, worst) = smallest(&measures.volume_ratio);
    if min_jacobian.is_nan() || min_jacobian <= 0.0 {
        return Err(VerifyError::Inverted {
            element_id: p.mesh.element_ids[worst],
            jacobian: min_jacobian,
        });
    }
    let (mut equilibrium_residual, node) = out_of_balance(c, u, &st.in_contact);
    // Nothing prescribed moves (an update back to zero): the answer is the reference
    // state, and a result within the tolerance of it is that answer; its residual relative
    // to reactions of rounding size would be rounding over rounding.
    let largest = u.iter().map(|v| v.amax()).fold(0.0, f64::max);
    if c.loads.max_prescribed() == 0.0 && !c.loads.has_forces() && largest <= tol {
        equilibrium_residual = 0.0;
    }
    // A body force's displacements are not known before the solve (the load scale is then
    // the mesh's diagonal): the answer's own largest displacement is the `u_max` of the
    // bound's reasoning.
    let scale =
        if c.loads.has_forces() { c.load_scale.min(largest.max(tol)) } else { c.load_scale };
    let equilibrium_bound = equilibrium_bound(tol, scale);
    if equilibrium_residual.is_nan() || equilibrium_residual > equilibrium_bound {
        return Err(VerifyError::Equilibrium {
            node_id: p.mesh.node_ids[node],
            residual: equilibrium_residual,
            bound: equilibrium_bound,
        });
    }
    Ok(Verification {
        in_contact: st.in_contact,
        max_penetration_after: st.max_penetration,
        min_jacobian,
        equilibrium_residual,
        equilibrium_bound,
        measures,
    })
}

/// The smallest value and its index (NaN wins: a NaN volume ratio is refused).
fn smallest(values: &[f64]) -> (f64, usize) {
    values.iter().copied().enumerate().fold((f64::INFINITY, 0), |(j, e), (k, x)| {
        if x < j || x.is_nan() && !j.is_nan() { (x, k) } else { (j, e) }
    })
}

/// The largest internal force at a free component of a node out of contact, relative to the
/// largest force at a constrained component or a node in contact (the reactions), and that
/// node. No reaction at all (nothing loaded): zero.
fn out_of_balance(c: &Composed, u: &[Vector3<f64>], in_contact: &[f64]) -> (f64, usize) {
    let mut ws = c.model.workspace();
    let mut f = vec![Vector3::zeros(); c.model.node_count()];
    if c.model.internal_forces_into(u, &mut ws, &mut f).is_err() {
        return (f64::INFINITY, 0); // an inverted element: refused before this by J
    }
    // Measurements are loads: their forces at the answer join the balance, and the largest
    // of them counts as a reaction does.
    let mut reaction = 0.0f64;
    if let Some(fit) = &c.fit {
        let mut data = vec![Vector3::zeros(); c.model.node_count()];
        fit.springs.add_forces_into(c.model.reference(), u, 1.0, &mut data);
        for (fi, di) in f.iter_mut().zip(&data) {
            reaction = reaction.max(di.norm());
            *fi += di;
        }
    }
    // So is a body force: its nodal loads enter the balance, the largest as a reaction.
    for (fi, e) in f.iter_mut().zip(c.loads.forces()) {
        reaction = reaction.max(e.norm());
        *fi -= e;
    }
    let mut worst = (0.0f64, 0usize);
    for (n, fi) in f.iter().enumerate() {
        let mut free = Vector3::zeros();
        let mut fixed = Vector3::zeros();
        for k in 0..3 {
            if c.loads.is_constrained(n, k) {
                fixed[k] = fi[k];
            } else {
                free[k] = fi[k];
            }
        }
        if in_contact[n] > 0.0 {
            reaction = reaction.max(fi.norm());
            continue;
        }
        reaction = reaction.max(fixed.norm());
        if free.norm() > worst.0 {
            worst = (free.norm(), n);
        }
    }
    if reaction > 0.0 { (worst.0 / reaction, worst.1) } else { (0.0, worst.1) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Prepared, Run};

    fn solved_cube() -> (Run, Vec<Vector3<f64>>) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/cube/uniaxial-t4.toml");
        let mut run = Run::prepare(Prepared::load(&path).unwrap()).unwrap();
        let s = run.solve(&mut |_| {}).unwrap();
        (run, s.solution.displacements)
    }

    /// A converged result passes with a residual far below its bound; the same result with
    /// one free node moved by a tenth of the load is refused, naming that node (its own
    /// out-of-balance force, k δ, exceeds any neighbour's share of it).
    #[test]
    fn a_result_out_of_equilibrium_is_refused_naming_the_node() {
        let (run, u) = solved_cube();
        let (p, c) = (&run.prepared, &run.composed);
        let v = verify(p, c, &u, run.settings.tolerance).unwrap();
        assert!(v.equilibrium_residual < 0.1 * v.equilibrium_bound, "{v:?}");
        assert!(v.min_jacobian > 0.0 && v.min_jacobian < 1.0, "{v:?}");
        let free = (0..u.len())
            .find(|&n| (0..3).all(|k| !c.loads.is_constrained(n, k)))
            .expect("the cube has free nodes");
        let mut w = u.clone();
        w[free].x += 0.01;
        match verify(p, c, &w, run.settings.tolerance) {
            Err(VerifyError::Equilibrium { node_id, residual, bound }) => {
                assert_eq!(node_id, p.mesh.node_ids[free]);
                assert!(residual > bound);
            }
            other => panic!("expected an equilibrium error, got {other:?}"),
        }
    }

    /// A result with an element turned inside out is refused, naming an element that holds
    /// the moved node.
    #[test]
    fn an_inverted_result_is_refused_naming_the_element() {
        let (run, u) = solved_cube();
        let (p, c) = (&run.prepared, &run.composed);
        let free = (0..u.len())
            .find(|&n| (0..3).all(|k| !c.loads.is_constrained(n, k)))
            .expect("the cube has free nodes");
        let mut w = u.clone();
        // Mirrored through the cube's centre: every element around the node inverts.
        let (lo, hi) = p.mesh.bounding_box().unwrap();
        let centre = lo + 0.5 * (hi - lo);
        w[free] -= 2.0 * (p.mesh.nodes[free] - centre);
        match verify(p, c, &w, run.settings.tolerance) {
            Err(VerifyError::Inverted { element_id, jacobian }) => {
                assert!(jacobian <= 0.0);
                let e = p.mesh.element_ids.iter().position(|&id| id == element_id).unwrap();
                assert!(p.mesh.elements[e].nodes().contains(&free), "element {element_id}");
            }
            other => panic!("expected an inversion error, got {other:?}"),
        }
    }
}
