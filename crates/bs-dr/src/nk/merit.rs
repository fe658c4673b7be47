//! The merit function of the line search: the natural residual of the equilibrium with
//! kinematic contact, in length units.
//!
//! `γ_a Π r_a` at free nodes (`Π` removes fixed components, `γ_a` the nodal compliance that
//! turns a force into the displacement that would relieve it) and `x_a − Proj(x_a + γ_a Π r_a)`
//! at contact nodes: zero exactly at the solution of the contact problem (a node inside the
//! cavity in balance, or on its surface pushed outward), and a Newton direction of the
//! semismooth system decreases it. An energy merit would need the contact as a constraint
//! on the line (projected trial points move the energy's minimiser) and an energy kernel for
//! every element technology; the natural residual uses only the forces and the projection
//! the iteration already computes.

use bs_mesh::Vector3;
use rayon::prelude::*;

use super::outcome::NewtonKrylovError;
use crate::contact::Contact;
use crate::linalg::multilevel::Projector;
use crate::model::Model;

/// The natural residual of a trial, and what it would be without the contact nodes whose
/// own term exceeds a bound (see [`natural_residual`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Merit {
    /// The Euclidean norm of the natural residual.
    pub value: f64,
    /// The same without the terms above the bound.
    pub without_jumps: f64,
    /// Contact nodes whose term is above the bound.
    pub jumps: usize,
}

#[cfg(test)]
impl Merit {
    /// A merit with no jumps.
    pub(crate) fn plain(value: f64) -> Self {
        Merit { value, without_jumps: value, jumps: 0 }
    }
}

/// The natural residual (see the module documentation), with the contact nodes whose own
/// term (a length) exceeds `jump` counted and also left out of [`Merit::without_jumps`]. On
/// a faceted skull the projection is discontinuous where a trial point crosses the points
/// equidistant from two faces (its closest point jumps from one to the other): such a node's
/// term jumps along the line whatever the rest of the residual does.
#[allow(clippy::too_many_arguments)]
pub(crate) fn natural_residual(
    model: &Model,
    u: &[Vector3<f64>],
    f: &[Vector3<f64>],
    contact_nodes: &[usize],
    is_contact: &[bool],
    gamma: &[f64],
    pi: &Projector,
    contact: &mut dyn Contact,
    jump: f64,
) -> Result<Merit, NewtonKrylovError> {
    let reference = model.reference();
    // Free nodes: the fixed components are projected out. Fixed-size chunks summed in order:
    // the same value for any thread count.
    let n = u.len();
    let chunks: Vec<f64> = (0..n.div_ceil(2048))
        .into_par_iter()
        .map(|c| {
            (c * 2048..((c + 1) * 2048).min(n))
                .filter(|&a| !is_contact[a])
                .map(|a| {
                    let r = if pi.constrained[a] { pi.matrix[a] * f[a] } else { f[a] };
                    (r * gamma[a]).norm_squared()
                })
                .sum::<f64>()
        })
        .collect();
    let mut m: f64 = chunks.iter().sum();
    let (mut jumped, mut jumps) = (0.0, 0);
    let jump2 = jump * jump;
    for (k, &a) in contact_nodes.iter().enumerate() {
        let x = reference[a] + u[a];
        let y = x - pi.matrix[a] * f[a] * gamma[a];
        let proj = contact.project(k, &y).ok_or_else(NewtonKrylovError::cannot_project)?;
        let target = if proj.outside { proj.point } else { y };
        let term = (x - target).norm_squared();
        if term > jump2 {
            jumped += term;
            jumps += 1;
        }
        m += term;
    }
    let without_jumps = (m - jumped).max(0.0).sqrt();
    Ok(Merit { value: m.sqrt(), without_jumps, jumps })
}
