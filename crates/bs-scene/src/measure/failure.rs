//! Why the data's pull could not be carried, in the words of the data: the measurement
//! whose pull it was and the element it inverts, with its position (never the solver's
//! advice to refine the mesh, which nobody showed would carry it).

use bs_dr::{LoadFailure, SolveError};
use bs_mesh::{Point3, Vector3};

use crate::prepare::Prepared;

/// The element a failed solve stopped at, if it stopped at one.
fn inverted(e: &SolveError) -> Option<usize> {
    match e {
        SolveError::ElementInverted { element, .. } => Some(*element),
        SolveError::LoadNotCarried { cause: LoadFailure::WouldInvert { element, .. }, .. } => {
            Some(*element)
        }
        SolveError::LoadNotCarried { fallback: Some(f), .. } => inverted(f),
        _ => None,
    }
}

/// Why the measurements' pull stopped the solve `e`: the measurement(s) whose node set
/// holds the element, its id and centroid; any other failure as the solver said it.
pub(crate) fn pull_failure(p: &Prepared, e: &SolveError) -> String {
    let keys: Vec<String> = p.measurements.iter().map(|m| m.key()).collect();
    let Some(el) = inverted(e).filter(|&el| el < p.mesh.elements.len()) else {
        return format!("the pull of {} could not be carried: {e}", keys.join(", "));
    };
    let nodes = p.mesh.elements[el].nodes();
    let centre = Point3::from(
        nodes.iter().map(|&n| p.mesh.nodes[n].coords).sum::<Vector3<f64>>() / nodes.len() as f64,
    );
    let holding: Vec<String> = p
        .measurements
        .iter()
        .filter(|m| {
            p.mesh.node_set(&m.nset).is_some_and(|set| nodes.iter().any(|n| set.contains(n)))
        })
        .map(|m| format!("{} on {}", m.key(), m.nset))
        .collect();
    let whose = if holding.is_empty() { keys.join(", ") } else { holding.join(", ") };
    format!(
        "the data's pull ({whose}) inverts element {} at ({:.1}, {:.1}, {:.1}) {}",
        p.mesh.element_ids[el],
        centre.x,
        centre.y,
        centre.z,
        p.scene.units.symbol()
    )
}
