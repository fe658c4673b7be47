//! Imposed data that invert an element by themselves: a tetrahedron whose four nodes are all
//! prescribed is inverted by the prescribed values alone when its volume at `X + u` is not
//! positive, whatever the solver does. Noisy intra-operative data imposed node by node do
//! that (1 mm of noise on a scanned surface, on the MNI152 regions brain), and the solver
//! could only report an inverted element and blame the mesh. Found before solving, it is
//! an error naming the element, the boundary whose data do it, and the fix: fit the data
//! (`[[measurement]]`) instead of imposing them.

use std::path::Path;

use bs_mesh::{ElementKind, Mesh, Point3, Vector3};

use crate::SceneError;
use crate::boundary::select_nodes;
use crate::scene::Scene;

/// What the checks read of a prepared scene: the scene (file and tables), the mesh and the
/// prescribed displacement of every node.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Imposed<'a> {
    pub path: &'a Path,
    pub scene: &'a Scene,
    pub mesh: &'a Mesh,
    pub prescribed: &'a [[Option<f64>; 3]],
}

/// The signed volume of the tetrahedron `x` (six times it, positive for a positively
/// oriented one).
fn volume6(x: [Point3<f64>; 4]) -> f64 {
    (x[1] - x[0]).cross(&(x[2] - x[0])).dot(&(x[3] - x[0]))
}

/// Refuses prescribed displacements that invert a fully prescribed tetrahedron (see the
/// module documentation).
pub(crate) fn check(p: Imposed<'_>) -> Result<(), SceneError> {
    let mesh = &p.mesh;
    let displacement = |n: usize| -> Option<Vector3<f64>> {
        let c = p.prescribed[n];
        Some(Vector3::new(c[0]?, c[1]?, c[2]?))
    };
    for (e, el) in mesh.elements.iter().enumerate() {
        if el.kind() != ElementKind::Tet4 {
            continue;
        }
        let nodes = el.nodes();
        let Some(u) = nodes.iter().map(|&n| displacement(n)).collect::<Option<Vec<_>>>() else {
            continue;
        };
        let before = volume6(std::array::from_fn(|k| mesh.nodes[nodes[k]]));
        let after = volume6(std::array::from_fn(|k| mesh.nodes[nodes[k]] + u[k]));
        if before > 0.0 && after / before <= 0.0 {
            return Err(SceneError::Element {
                scene: p.path.to_path_buf(),
                element_id: mesh.element_ids[e],
                message: format!(
                    "the prescribed displacements of its four nodes invert it by themselves \
                     (volume ratio {:.3}): {}. No solver can carry that; noisy data imposed node \
                     by node do it. Fit the data instead: a [[measurement]] with points = the \
                     scan and sigma = its noise (docs/fit.md)",
                    after / before,
                    source(p, nodes)
                ),
            });
        }
    }
    Ok(())
}

/// The error of a solve that stopped at an inverted element: when that element holds nodes
/// of an intra-operative boundary (a surface, landmarks or a displacement file imposed node
/// by node), the error says that the imposed data fold it and points to `[[measurement]]`,
/// instead of the solver's advice to refine the mesh; any other error as it is.
pub(crate) fn explain(p: Imposed<'_>, e: bs_dr::SolveError) -> SceneError {
    use bs_dr::{LoadFailure, SolveError};
    let (element, how) = match &e {
        SolveError::ElementInverted { element, jacobian, .. } => {
            (Some(*element), format!("its volume ratio reached {jacobian:.3e}"))
        }
        SolveError::LoadNotCarried {
            cause: LoadFailure::WouldInvert { element, .. },
            reached,
            ..
        } => (Some(*element), format!("at {:.1} % of the data", 100.0 * reached)),
        _ => (None, String::new()),
    };
    let Some(element) = element.filter(|&el| el < p.mesh.elements.len()) else {
        return SceneError::Solve(e);
    };
    let nodes = p.mesh.elements[element].nodes();
    let Some(data) = imposing(p, nodes) else { return SceneError::Solve(e) };
    SceneError::Element {
        scene: p.path.to_path_buf(),
        element_id: p.mesh.element_ids[element],
        message: format!(
            "the solver could not impose {data} without inverting this element ({how}): \
             imposed node by node, a measurement's noise folds the surface's elements. Fit \
             the data instead: a [[measurement]] with points = the scan and sigma = its noise \
             (docs/fit.md)"
        ),
    }
}

/// The intra-operative boundary (surface, landmarks, displacement file) holding any of
/// `nodes`, described for a message.
fn imposing(p: Imposed<'_>, nodes: &[usize]) -> Option<String> {
    for (i, b) in p.scene.boundaries.iter().enumerate() {
        let file = b.surface.as_ref().or(b.landmarks.as_ref()).or(b.displacement_file.as_ref());
        let Some(file) = file else { continue };
        let Ok((name, set)) = select_nodes(p.path, p.scene, p.mesh, i, b) else { continue };
        if nodes.iter().any(|n| set.contains(n)) {
            return Some(format!("[[boundary]] #{} {} on {name}", i + 1, file.display()));
        }
    }
    None
}

/// Which `[[boundary]]` prescribes `nodes` (its number, node set and file).
fn source(p: Imposed<'_>, nodes: &[usize]) -> String {
    for (i, b) in p.scene.boundaries.iter().enumerate() {
        if b.displacement_file.is_some() || b.fix.is_some() {
            continue;
        }
        let Ok((name, set)) = select_nodes(p.path, p.scene, p.mesh, i, b) else { continue };
        if nodes.iter().any(|n| set.binary_search(n).is_ok() || set.contains(n)) {
            let file = b.surface.as_ref().or(b.landmarks.as_ref());
            let data = file.map_or(String::new(), |f| format!(" {}", f.display()));
            return format!("its nodes are held by [[boundary]] #{} on {name}{data}", i + 1);
        }
    }
    "its nodes are all prescribed".into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_volume_changes_sign_with_the_orientation() {
        let x = [
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        assert_eq!(volume6(x), 1.0);
        assert_eq!(volume6([x[1], x[0], x[2], x[3]]), -1.0);
    }
}
