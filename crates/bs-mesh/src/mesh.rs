//! The volume mesh model.

use std::collections::BTreeMap;

use nalgebra::Point3;

/// Element shapes supported by the solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ElementKind {
    /// 4-node linear tetrahedron (Abaqus C3D4, Gmsh type 4, VTK 10).
    Tet4,
    /// 8-node trilinear hexahedron (Abaqus C3D8/C3D8R, Gmsh type 5, VTK 12).
    Hex8,
}

/// The 6 edges of a tetrahedron, as pairs of local node positions.
const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// The 12 edges of a hexahedron (Abaqus/VTK node order): bottom ring, top ring, pillars.
const HEX_EDGES: [[usize; 2]; 12] = [
    [0, 1],
    [1, 2],
    [2, 3],
    [3, 0],
    [4, 5],
    [5, 6],
    [6, 7],
    [7, 4],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

impl ElementKind {
    /// The edges of this shape as pairs of local node positions (the one table every edge
    /// computation in the workspace uses).
    pub const fn edges(self) -> &'static [[usize; 2]] {
        match self {
            ElementKind::Tet4 => &TET_EDGES,
            ElementKind::Hex8 => &HEX_EDGES,
        }
    }

    /// Number of nodes of this element shape.
    pub const fn node_count(self) -> usize {
        match self {
            ElementKind::Tet4 => 4,
            ElementKind::Hex8 => 8,
        }
    }

    /// Short lowercase name (`"tet4"`, `"hex8"`).
    pub const fn name(self) -> &'static str {
        match self {
            ElementKind::Tet4 => "tet4",
            ElementKind::Hex8 => "hex8",
        }
    }

    /// Faces as local node indices, ordered so that the right-hand normal points out of a
    /// positively oriented element. Tet faces are triangles; hex faces are quads (the fourth
    /// entry is used).
    pub(crate) fn faces(self) -> &'static [[usize; 4]] {
        match self {
            // Tet (0,1,2,3) positively oriented when (1-0)x(2-0)·(3-0) > 0.
            ElementKind::Tet4 => &[[0, 2, 1, 0], [0, 1, 3, 0], [1, 2, 3, 0], [0, 3, 2, 0]],
            // Hex in Abaqus/VTK order: bottom 0-1-2-3, top 4-5-6-7.
            ElementKind::Hex8 => &[
                [0, 3, 2, 1],
                [4, 5, 6, 7],
                [0, 1, 5, 4],
                [1, 2, 6, 5],
                [2, 3, 7, 6],
                [3, 0, 4, 7],
            ],
        }
    }
}

/// One element: its shape and node indices (0-based indices into [`Mesh::nodes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Element {
    kind: ElementKind,
    nodes: [usize; 8],
}

impl Element {
    /// A linear tetrahedron.
    pub const fn tet4(n: [usize; 4]) -> Self {
        Element { kind: ElementKind::Tet4, nodes: [n[0], n[1], n[2], n[3], 0, 0, 0, 0] }
    }

    /// A trilinear hexahedron (bottom face 0-1-2-3, top face 4-5-6-7, Abaqus/VTK order).
    pub const fn hex8(n: [usize; 8]) -> Self {
        Element { kind: ElementKind::Hex8, nodes: n }
    }

    /// Builds an element from a node slice whose length selects the kind (4 or 8).
    pub fn from_nodes(nodes: &[usize]) -> Option<Self> {
        match nodes.len() {
            4 => Some(Self::tet4([nodes[0], nodes[1], nodes[2], nodes[3]])),
            8 => {
                let mut n = [0; 8];
                n.copy_from_slice(nodes);
                Some(Self::hex8(n))
            }
            _ => None,
        }
    }

    /// The element's shape.
    pub const fn kind(&self) -> ElementKind {
        self.kind
    }

    /// Node indices, `kind().node_count()` of them.
    pub fn nodes(&self) -> &[usize] {
        &self.nodes[..self.kind.node_count()]
    }

    /// Mutable node indices (used by readers that renumber).
    pub fn nodes_mut(&mut self) -> &mut [usize] {
        let n = self.kind.node_count();
        &mut self.nodes[..n]
    }
}

/// A volume mesh of T4 and H8 elements with named sets.
///
/// Node and element *indices* are 0-based positions in the vectors; *ids* are the labels of
/// the source file (Abaqus and Gmsh number from 1, VTK from 0) and are what users see in
/// outputs and error messages. Sets store sorted, duplicate-free indices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Node coordinates in the caller's length unit.
    pub nodes: Vec<Point3<f64>>,
    /// External node ids, one per node.
    pub node_ids: Vec<u64>,
    /// Elements.
    pub elements: Vec<Element>,
    /// External element ids, one per element.
    pub element_ids: Vec<u64>,
    /// Named node sets (sorted node indices).
    pub node_sets: BTreeMap<String, Vec<usize>>,
    /// Named element sets (sorted element indices).
    pub element_sets: BTreeMap<String, Vec<usize>>,
}

impl Mesh {
    /// A mesh with ids equal to 1-based positions and no sets.
    pub fn new(nodes: Vec<Point3<f64>>, elements: Vec<Element>) -> Self {
        let node_ids = (1..=nodes.len() as u64).collect();
        let element_ids = (1..=elements.len() as u64).collect();
        Mesh { nodes, node_ids, elements, element_ids, ..Default::default() }
    }

    /// Number of elements of each kind, `(tet4, hex8)`.
    pub fn count_by_kind(&self) -> (usize, usize) {
        let tets = self.elements.iter().filter(|e| e.kind() == ElementKind::Tet4).count();
        (tets, self.elements.len() - tets)
    }

    /// Axis-aligned bounding box `(min, max)`, or `None` for a mesh without nodes.
    pub fn bounding_box(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        bounding_box(&self.nodes)
    }

    /// Looks a node set up by name: exact match first, then ASCII case-insensitive (Abaqus
    /// names are case-insensitive).
    pub fn node_set(&self, name: &str) -> Option<&[usize]> {
        lookup(&self.node_sets, name)
    }

    /// Looks an element set up by name, like [`Mesh::node_set`].
    pub fn element_set(&self, name: &str) -> Option<&[usize]> {
        lookup(&self.element_sets, name)
    }

    /// Signed volume of element `e` (positive for a correctly oriented element). For hexes it
    /// is the exact volume of the trilinear element (sum over a 2×2×2 Gauss rule).
    pub fn element_volume(&self, e: usize) -> f64 {
        element_volume(&self.nodes, &self.elements[e])
    }

    /// Index of the node with external id `id` (linear scan; build a map for many lookups).
    pub fn node_index(&self, id: u64) -> Option<usize> {
        self.node_ids.iter().position(|&i| i == id)
    }
}

fn lookup<'a>(sets: &'a BTreeMap<String, Vec<usize>>, name: &str) -> Option<&'a [usize]> {
    sets.get(name)
        .or_else(|| sets.iter().find(|(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v))
        .map(Vec::as_slice)
}

pub(crate) fn bounding_box(points: &[Point3<f64>]) -> Option<(Point3<f64>, Point3<f64>)> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))))
}

/// Signed volume of a tetrahedron.
pub(crate) fn tet_volume(
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
    d: &Point3<f64>,
) -> f64 {
    (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0
}

pub(crate) fn element_volume(nodes: &[Point3<f64>], e: &Element) -> f64 {
    let n = e.nodes();
    match e.kind() {
        ElementKind::Tet4 => tet_volume(&nodes[n[0]], &nodes[n[1]], &nodes[n[2]], &nodes[n[3]]),
        ElementKind::Hex8 => {
            let g = 1.0 / 3f64.sqrt();
            let mut vol = 0.0;
            for &xi in &[-g, g] {
                for &eta in &[-g, g] {
                    for &zeta in &[-g, g] {
                        vol += hex_jacobian_det(nodes, n, xi, eta, zeta);
                    }
                }
            }
            vol
        }
    }
}

/// Natural (reference) coordinates of the 8 hex nodes in Abaqus/VTK order, the one table
/// every hexahedron computation in the workspace uses.
pub const HEX_REFERENCE: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

pub(crate) use HEX_REFERENCE as HEX_REF;

/// Determinant of the isoparametric Jacobian of a hex at reference point (xi, eta, zeta).
pub(crate) fn hex_jacobian_det(
    nodes: &[Point3<f64>],
    n: &[usize],
    xi: f64,
    eta: f64,
    zeta: f64,
) -> f64 {
    let mut j = nalgebra::Matrix3::<f64>::zeros();
    for (a, r) in HEX_REF.iter().enumerate() {
        let d = [
            0.125 * r[0] * (1.0 + r[1] * eta) * (1.0 + r[2] * zeta),
            0.125 * r[1] * (1.0 + r[0] * xi) * (1.0 + r[2] * zeta),
            0.125 * r[2] * (1.0 + r[0] * xi) * (1.0 + r[1] * eta),
        ];
        let p = nodes[n[a]];
        for row in 0..3 {
            for col in 0..3 {
                j[(row, col)] += p[row] * d[col];
            }
        }
    }
    j.determinant()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn unit_hex() -> Mesh {
        let nodes = HEX_REF
            .iter()
            .map(|r| Point3::new(0.5 * (r[0] + 1.0), 0.5 * (r[1] + 1.0), 0.5 * (r[2] + 1.0)))
            .collect();
        Mesh::new(nodes, vec![Element::hex8([0, 1, 2, 3, 4, 5, 6, 7])])
    }

    #[test]
    fn unit_hex_has_unit_volume() {
        approx::assert_relative_eq!(unit_hex().element_volume(0), 1.0, epsilon = 1e-14);
    }

    #[test]
    fn reference_tet_volume_is_one_sixth() {
        let nodes = vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let m = Mesh::new(nodes, vec![Element::tet4([0, 1, 2, 3])]);
        approx::assert_relative_eq!(m.element_volume(0), 1.0 / 6.0, epsilon = 1e-15);
        let swapped = Mesh { elements: vec![Element::tet4([0, 2, 1, 3])], ..m };
        approx::assert_relative_eq!(swapped.element_volume(0), -1.0 / 6.0, epsilon = 1e-15);
    }

    #[test]
    fn set_lookup_falls_back_to_case_insensitive() {
        let mut m = unit_hex();
        m.node_sets.insert("FIXED".into(), vec![0, 1]);
        assert_eq!(m.node_set("FIXED"), Some(&[0usize, 1][..]));
        assert_eq!(m.node_set("fixed"), Some(&[0usize, 1][..]));
        assert_eq!(m.node_set("other"), None);
    }
}
