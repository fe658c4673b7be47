//! Exact brain–skull gaps: the initial check (no brain node may start outside the skull)
//! and the distances the final contact check measures, independent of the contact handler
//! the solver used.

use bs_contact::ParryContact;
use rayon::prelude::*;

use crate::SceneError;
use crate::compose::Composed;
use crate::prepare::Prepared;

impl Composed {
    /// Slave nodes outside the skull in the reference configuration: an error listing their
    /// ids and distances (a run would snap them onto the skull at the first step).
    pub fn check_initial_gap(&self, p: &Prepared) -> Result<Option<(f64, f64)>, SceneError> {
        let Some(exact) = &self.exact else { return Ok(None) };
        // Exact distances (parry's BVH and the exact point–triangle projection, equal to
        // brute force at any distance: bs-contact's tests).
        let rows = exact_gaps(exact, self.slaves.iter().map(|&n| p.mesh.nodes[n]));
        let outside: Vec<(usize, f64)> = rows
            .iter()
            .zip(&self.slaves)
            .filter(|(r, _)| r.outside)
            .map(|(r, &n)| (n, -r.signed_distance))
            .collect();
        if !outside.is_empty() {
            let mut nodes: Vec<(u64, f64)> =
                outside.iter().map(|&(n, d)| (p.mesh.node_ids[n], d)).collect();
            nodes.sort_by(|a, b| b.1.total_cmp(&a.1));
            return Err(SceneError::OutsideSkull { scene: p.path.clone(), nodes });
        }
        let min = rows.iter().map(|r| r.signed_distance).fold(f64::INFINITY, f64::min);
        let max = rows.iter().map(|r| r.signed_distance).fold(f64::NEG_INFINITY, f64::max);
        Ok(Some((min, max)))
    }
}

/// Exact signed distances of `points` to the skull (see [`ParryContact::project_exact`]).
pub fn exact_gaps(
    exact: &ParryContact,
    points: impl Iterator<Item = bs_mesh::Point3<f64>>,
) -> Vec<bs_contact::GapRow> {
    let points: Vec<bs_mesh::Point3<f64>> = points.collect();
    points
        .par_iter()
        .map(|&q| match exact.project_exact(&q) {
            Some(pr) => bs_contact::GapRow {
                signed_distance: pr.signed_distance,
                closest: pr.point,
                outside: pr.outside,
            },
            None => {
                bs_contact::GapRow { signed_distance: f64::NEG_INFINITY, closest: q, outside: true }
            }
        })
        .collect()
}
