//! Mesh validation with typed errors.

use crate::mesh::{HEX_REF, element_volume, hex_jacobian_det};
use crate::{ElementKind, Mesh};

/// A problem found in a volume mesh. Messages name the entity by its file id and say how to
/// fix it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The mesh has no elements.
    #[error("the mesh has no volume elements (T4 or H8); mesh the volume, not only its surface")]
    NoElements,
    /// `node_ids`/`element_ids` lengths disagree with the node/element counts.
    #[error("internal inconsistency: {what}")]
    Inconsistent {
        /// What disagrees.
        what: String,
    },
    /// A coordinate is NaN or infinite.
    #[error("node {node_id} has a non-finite coordinate {coords:?}; fix the mesh file")]
    NonFiniteCoordinate {
        /// File id of the node.
        node_id: u64,
        /// Its coordinates.
        coords: [f64; 3],
    },
    /// An element refers to a node index that does not exist.
    #[error(
        "element {element_id} refers to node index {node}, but the mesh has only {count} nodes"
    )]
    NodeOutOfRange {
        /// File id of the element.
        element_id: u64,
        /// The bad 0-based index.
        node: usize,
        /// Number of nodes.
        count: usize,
    },
    /// An element uses the same node twice.
    #[error("element {element_id} uses node {node_id} more than once (collapsed element)")]
    RepeatedNode {
        /// File id of the element.
        element_id: u64,
        /// File id of the repeated node.
        node_id: u64,
    },
    /// Negative volume (tets) or a negative corner Jacobian (hexes).
    #[error(
        "element {element_id} (index {index}) is inverted: {measure} = {value:.3e}; swap two \
         nodes of a tet (e.g. 2 and 3) or the top and bottom faces of a hex, or remesh"
    )]
    Inverted {
        /// File id of the element.
        element_id: u64,
        /// 0-based element index.
        index: usize,
        /// "volume" or "corner Jacobian".
        measure: &'static str,
        /// The negative value.
        value: f64,
    },
    /// Zero volume relative to the element size.
    #[error(
        "element {element_id} (index {index}) is degenerate: volume {volume:.3e} is tiny for \
         its edge length {edge:.3e}; remove slivers or remesh"
    )]
    Degenerate {
        /// File id of the element.
        element_id: u64,
        /// 0-based element index.
        index: usize,
        /// Its signed volume.
        volume: f64,
        /// Its longest edge.
        edge: f64,
    },
    /// Two nodes at the same position (a crack in the mesh if both are used).
    #[error(
        "nodes {first_id} and {second_id} coincide at {coords:?}; merge duplicate nodes (gmsh: \
         Coherence) or the elements on either side are not connected"
    )]
    DuplicateNodes {
        /// File id of the first node.
        first_id: u64,
        /// File id of the second node.
        second_id: u64,
        /// The shared position.
        coords: [f64; 3],
    },
    /// A set refers to a missing node or element.
    #[error("set '{set}' refers to index {index}, beyond the {count} entries of the mesh")]
    SetOutOfRange {
        /// Set name.
        set: String,
        /// The bad index.
        index: usize,
        /// Number of nodes or elements.
        count: usize,
    },
}

/// The outcome of [`Mesh::validate`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ValidationReport {
    /// Problems that make the mesh unusable for simulation.
    pub errors: Vec<MeshError>,
    /// Nodes used by no element (harmless for reading, but they carry no mass: the solver
    /// ignores them). File ids.
    pub unused_node_ids: Vec<u64>,
}

impl ValidationReport {
    /// No errors (unused nodes are allowed).
    pub fn is_ok(&self) -> bool {
        self.errors.is_empty()
    }

    /// The first error, for callers that stop at one.
    pub fn first_error(&self) -> Option<&MeshError> {
        self.errors.first()
    }
}

/// Relative volume below which an element counts as degenerate: `|V| < TOL · L³` with `L`
/// its longest edge. A regular tet has `V/L³ ≈ 0.118`; 1e-8 flags only true slivers and
/// collapsed elements, which make the explicit time step vanish.
const DEGENERATE_TOL: f64 = 1e-8;

impl Mesh {
    /// Checks the mesh and lists every problem (does not stop at the first).
    pub fn validate(&self) -> ValidationReport {
        let mut r = ValidationReport::default();
        let n = self.nodes.len();
        if self.node_ids.len() != n || self.element_ids.len() != self.elements.len() {
            r.errors.push(MeshError::Inconsistent {
                what: format!(
                    "{} nodes but {} node ids, {} elements but {} element ids",
                    n,
                    self.node_ids.len(),
                    self.elements.len(),
                    self.element_ids.len()
                ),
            });
            return r;
        }
        if self.elements.is_empty() {
            r.errors.push(MeshError::NoElements);
        }
        for (i, p) in self.nodes.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                r.errors.push(MeshError::NonFiniteCoordinate {
                    node_id: self.node_ids[i],
                    coords: [p.x, p.y, p.z],
                });
            }
        }
        let finite = r.errors.is_empty();
        let mut used = vec![false; n];
        for (index, el) in self.elements.iter().enumerate() {
            let element_id = self.element_ids[index];
            let nodes = el.nodes();
            if let Some(&node) = nodes.iter().find(|&&v| v >= n) {
                r.errors.push(MeshError::NodeOutOfRange { element_id, node, count: n });
                continue;
            }
            for &v in nodes {
                used[v] = true;
            }
            if let Some(pos) = (1..nodes.len()).find(|&i| nodes[..i].contains(&nodes[i])) {
                r.errors.push(MeshError::RepeatedNode {
                    element_id,
                    node_id: self.node_ids[nodes[pos]],
                });
                continue;
            }
            if let Some(e) = finite.then(|| self.check_shape(index)).flatten() {
                r.errors.push(e);
            }
        }
        for (name, set) in &self.node_sets {
            if let Some(&index) = set.iter().find(|&&i| i >= n) {
                r.errors.push(MeshError::SetOutOfRange { set: name.clone(), index, count: n });
            }
        }
        for (name, set) in &self.element_sets {
            if let Some(&index) = set.iter().find(|&&i| i >= self.elements.len()) {
                r.errors.push(MeshError::SetOutOfRange {
                    set: name.clone(),
                    index,
                    count: self.elements.len(),
                });
            }
        }
        if finite {
            r.errors.extend(self.duplicate_nodes(&used));
        }
        r.unused_node_ids = (0..n).filter(|&i| !used[i]).map(|i| self.node_ids[i]).collect();
        r
    }

    /// Inversion and degeneracy of one element with in-range, distinct, finite nodes.
    fn check_shape(&self, index: usize) -> Option<MeshError> {
        let el = &self.elements[index];
        let element_id = self.element_ids[index];
        let nodes = el.nodes();
        let volume = element_volume(&self.nodes, el);
        let edge = longest_edge(&self.nodes, el.kind(), nodes);
        match el.kind() {
            ElementKind::Tet4 if volume < 0.0 => {
                return Some(MeshError::Inverted {
                    element_id,
                    index,
                    measure: "volume",
                    value: volume,
                });
            }
            ElementKind::Hex8 => {
                let worst = HEX_REF
                    .iter()
                    .map(|r| hex_jacobian_det(&self.nodes, nodes, r[0], r[1], r[2]))
                    .fold(f64::INFINITY, f64::min);
                if worst < 0.0 {
                    return Some(MeshError::Inverted {
                        element_id,
                        index,
                        measure: "corner Jacobian",
                        value: worst,
                    });
                }
            }
            ElementKind::Tet4 => {}
        }
        (volume.abs() <= DEGENERATE_TOL * edge.powi(3)).then_some(MeshError::Degenerate {
            element_id,
            index,
            volume,
            edge,
        })
    }

    /// Pairs of used nodes at exactly the same position (sorted sweep, O(n log n)).
    fn duplicate_nodes(&self, used: &[bool]) -> Vec<MeshError> {
        let mut order: Vec<usize> = (0..self.nodes.len()).filter(|&i| used[i]).collect();
        let key = |i: usize| {
            let p = self.nodes[i];
            [p.x, p.y, p.z]
        };
        order.sort_unstable_by(|&a, &b| key(a).partial_cmp(&key(b)).expect("finite coordinates"));
        order
            .windows(2)
            .filter(|w| key(w[0]) == key(w[1]))
            .map(|w| MeshError::DuplicateNodes {
                first_id: self.node_ids[w[0]],
                second_id: self.node_ids[w[1]],
                coords: key(w[0]),
            })
            .collect()
    }
}

fn longest_edge(points: &[crate::Point3<f64>], kind: ElementKind, nodes: &[usize]) -> f64 {
    kind.edges()
        .iter()
        .map(|[a, b]| (points[nodes[*a]] - points[nodes[*b]]).norm())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Element, Point3};

    fn tet() -> Mesh {
        let nodes = vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        Mesh::new(nodes, vec![Element::tet4([0, 1, 2, 3])])
    }

    #[test]
    fn good_tet_and_hex_pass() {
        assert!(tet().validate().is_ok());
        assert!(crate::mesh::tests::unit_hex().validate().is_ok());
    }

    #[test]
    fn inverted_tet_names_its_id_and_volume() {
        let mut m = tet();
        m.elements[0] = Element::tet4([0, 2, 1, 3]);
        m.element_ids[0] = 42;
        let r = m.validate();
        assert_eq!(
            r.errors,
            vec![MeshError::Inverted {
                element_id: 42,
                index: 0,
                measure: "volume",
                value: -1.0 / 6.0
            }]
        );
        assert!(r.errors[0].to_string().contains("element 42"));
    }

    #[test]
    fn hex_with_swapped_top_and_bottom_is_inverted() {
        let mut m = crate::mesh::tests::unit_hex();
        m.elements[0] = Element::hex8([4, 5, 6, 7, 0, 1, 2, 3]);
        assert!(matches!(
            m.validate().errors[..],
            [MeshError::Inverted { measure: "corner Jacobian", .. }]
        ));
    }

    #[test]
    fn flat_tet_is_degenerate() {
        let mut m = tet();
        m.nodes[3] = Point3::new(0.3, 0.3, 0.0);
        assert!(matches!(m.validate().errors[..], [MeshError::Degenerate { element_id: 1, .. }]));
    }

    #[test]
    fn out_of_range_repeated_nan_duplicate_and_unused_are_all_reported() {
        let mut m = tet();
        m.elements.push(Element::tet4([0, 1, 2, 9]));
        m.elements.push(Element::tet4([0, 1, 1, 3]));
        m.element_ids = vec![1, 2, 3];
        m.nodes.push(Point3::new(5.0, 5.0, 5.0)); // unused node id 5
        m.node_ids.push(5);
        let r = m.validate();
        assert_eq!(r.errors[0], MeshError::NodeOutOfRange { element_id: 2, node: 9, count: 5 });
        assert_eq!(r.errors[1], MeshError::RepeatedNode { element_id: 3, node_id: 2 });
        assert_eq!(r.unused_node_ids, vec![5]);

        let mut d = tet();
        d.nodes.push(Point3::new(0.0, 0.0, 1.0));
        d.node_ids.push(5);
        d.elements.push(Element::tet4([1, 2, 0, 4]).flip_if_needed(&d.nodes));
        d.element_ids.push(2);
        assert_eq!(
            d.validate().errors,
            vec![MeshError::DuplicateNodes { first_id: 4, second_id: 5, coords: [0.0, 0.0, 1.0] }]
        );

        let mut nan = tet();
        nan.nodes[2].y = f64::NAN;
        assert!(matches!(
            nan.validate().errors[..],
            [MeshError::NonFiniteCoordinate { node_id: 3, .. }]
        ));
    }

    trait FlipIfNeeded {
        fn flip_if_needed(self, nodes: &[Point3<f64>]) -> Self;
    }
    impl FlipIfNeeded for Element {
        fn flip_if_needed(mut self, nodes: &[Point3<f64>]) -> Self {
            if element_volume(nodes, &self) < 0.0 {
                self.nodes_mut().swap(1, 2);
            }
            self
        }
    }
}
