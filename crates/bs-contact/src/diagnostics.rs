//! Diagnostics on a master surface, apart from the enforcement loop: the initial-state check
//! (which slaves start outside the cavity) and the gap table (`brainshift gap`). Both are
//! exact at any distance through [`MasterSurface::project_exact`].

use nalgebra::Point3;

use crate::ContactError;
use crate::master::MasterSurface;
use crate::query::ClosestPoint;

/// A slave node found outside the cavity before the first step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutsideNode {
    /// Index of the node in the positions array.
    pub node: usize,
    /// Signed distance (negative: how far outside).
    pub signed_distance: f64,
    /// Closest point of the skull.
    pub closest: Point3<f64>,
}

/// Lists the slave nodes that are outside the cavity at the start, exactly
/// ([`MasterSurface::project_exact`]: every face, run once). An empty list means the initial
/// state is admissible; otherwise the caller should report the nodes (or project them first,
/// knowingly). Non-finite positions have no closest point and are not listed.
pub fn check_initial(
    master: &MasterSurface,
    slaves: &[usize],
    positions: &[Point3<f64>],
) -> Result<Vec<OutsideNode>, ContactError> {
    let mut out = Vec::new();
    for &node in slaves {
        let p = positions
            .get(node)
            .ok_or(ContactError::SlaveOutOfRange { node, node_count: positions.len() })?;
        if let Some(proj) = master.project_exact(p)
            && proj.outside
        {
            out.push(OutsideNode {
                node,
                signed_distance: proj.signed_distance,
                closest: proj.point,
            });
        }
    }
    Ok(out)
}

/// One row of the gap diagnostic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapRow {
    /// Signed distance to the skull: positive inside the cavity, negative outside.
    pub signed_distance: f64,
    /// Closest point on the skull.
    pub closest: Point3<f64>,
    /// Whether the point is outside the cavity.
    pub outside: bool,
}

/// The gap diagnostic (`brainshift gap`): for each query point the exact signed distance to
/// the skull, the closest point and the outside verdict, computed with `handler`. Where the
/// handler gives no answer or the point is farther from the surface than the handler's
/// [`reach`](ClosestPoint::reach) (the paper's algorithm is exact only within the per-step
/// penetration bound `d`), the row is computed by
/// [`MasterSurface::project_exact`] (every face), so every row is exact.
pub fn gap<H: ClosestPoint>(
    handler: &mut H,
    master: &MasterSurface,
    points: &[Point3<f64>],
) -> Vec<GapRow> {
    let reach = handler.reach();
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let proj = match handler.closest(i, p) {
                Some(proj) if proj.signed_distance.abs() <= reach => Some(proj),
                _ => master.project_exact(p),
            };
            match proj {
                Some(proj) => GapRow {
                    signed_distance: proj.signed_distance,
                    closest: proj.point,
                    outside: proj.outside,
                },
                // A non-finite point has no closest point.
                None => GapRow { signed_distance: f64::NAN, closest: *p, outside: false },
            }
        })
        .collect()
}
