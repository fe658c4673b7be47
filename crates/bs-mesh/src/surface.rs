//! Triangle surfaces and their topology.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

/// A triangle surface mesh. Triangles are counter-clockwise seen from outside when the
/// surface is outward oriented.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriSurface {
    /// Vertex coordinates.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[usize; 3]>,
}

/// An undirected edge of a surface with the (up to two) faces that use it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    /// End vertices, `nodes[0] < nodes[1]`.
    pub nodes: [usize; 2],
    /// The first two faces using the edge; `faces[1]` is `None` on an open boundary.
    pub faces: [Option<usize>; 2],
    /// How many faces use the edge (2 on a closed manifold surface).
    pub face_count: usize,
}

/// Adjacency of a [`TriSurface`]: what the contact search and the checks walk.
///
/// Built once by [`TriSurface::topology`]; every list is in compressed (offset) form so that
/// lookups in hot loops allocate nothing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceTopology {
    node_face_offsets: Vec<usize>,
    node_faces: Vec<usize>,
    node_edge_offsets: Vec<usize>,
    node_edges: Vec<usize>,
    /// All undirected edges.
    pub edges: Vec<Edge>,
    /// The three edges of each face: edge `k` joins corners `k` and `k + 1 (mod 3)`.
    pub face_edges: Vec<[usize; 3]>,
    /// Unit outward (right-hand) normal of each face; zero for a degenerate face.
    pub face_normals: Vec<Vector3<f64>>,
    /// Edges used by one face only.
    pub boundary_edges: Vec<usize>,
    /// Edges used by three or more faces.
    pub non_manifold_edges: Vec<usize>,
    /// Edges whose two faces traverse them in the same direction (inconsistent orientation).
    pub misoriented_edges: Vec<usize>,
    /// Vertices whose faces do not form a single fan (e.g. two cones touching at a tip).
    pub non_manifold_vertices: Vec<usize>,
    /// Vertices used by no face.
    pub unused_vertices: Vec<usize>,
}

impl SurfaceTopology {
    /// Faces incident to vertex `v`.
    pub fn faces_of_node(&self, v: usize) -> &[usize] {
        &self.node_faces[self.node_face_offsets[v]..self.node_face_offsets[v + 1]]
    }

    /// Edges incident to vertex `v`.
    pub fn edges_of_node(&self, v: usize) -> &[usize] {
        &self.node_edges[self.node_edge_offsets[v]..self.node_edge_offsets[v + 1]]
    }

    /// Normal of edge `e`: the normalised sum of its faces' normals (the paper's definition).
    pub fn edge_normal(&self, e: usize) -> Vector3<f64> {
        let sum: Vector3<f64> =
            self.edges[e].faces.iter().flatten().map(|&f| self.face_normals[f]).sum();
        sum.try_normalize(0.0).unwrap_or_else(Vector3::zeros)
    }

    /// Normal of vertex `v`: the normalised sum of its faces' normals (the paper's definition).
    pub fn node_normal(&self, v: usize) -> Vector3<f64> {
        let sum: Vector3<f64> = self.faces_of_node(v).iter().map(|&f| self.face_normals[f]).sum();
        sum.try_normalize(0.0).unwrap_or_else(Vector3::zeros)
    }
}

/// Two triangles of one surface that cross or overlap beyond what they share.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SelfIntersection {
    /// The smaller triangle index.
    pub first: usize,
    /// The larger triangle index.
    pub second: usize,
}

/// Why a surface cannot serve as a closed, outward-oriented boundary (e.g. a skull).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    /// No triangles at all.
    #[error("the surface has no triangles")]
    Empty,
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {vertex}, but the surface has {count} vertices")]
    VertexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// The bad vertex index.
        vertex: usize,
        /// Number of vertices.
        count: usize,
    },
    /// The surface has holes.
    #[error(
        "the surface is open: {count} edges belong to one triangle only (e.g. the edge between \
         vertices {} and {}); close the holes (e.g. gmsh or MeshLab 'close holes') before use",
        example[0], example[1]
    )]
    Open {
        /// Number of boundary edges.
        count: usize,
        /// One boundary edge (vertex indices).
        example: [usize; 2],
    },
    /// An edge or vertex is shared by more than one sheet.
    #[error(
        "the surface is not manifold: {count} edges or vertices are shared by more than two \
         triangles or sheets (e.g. vertex {example}); split touching parts or remesh"
    )]
    NonManifold {
        /// Number of non-manifold edges and vertices.
        count: usize,
        /// One offending vertex.
        example: usize,
    },
    /// Neighbouring triangles disagree on the orientation.
    #[error(
        "the triangles are not consistently oriented: {count} edges are traversed in the same \
         direction by both of their triangles (e.g. vertices {} and {}); reorient the surface \
         (e.g. meshio/MeshLab 'reorient coherently')",
        example[0], example[1]
    )]
    Inconsistent {
        /// Number of misoriented edges.
        count: usize,
        /// One misoriented edge.
        example: [usize; 2],
    },
    /// A triangle with zero area: a repeated vertex or three collinear vertices.
    #[error(
        "triangle {triangle} is degenerate: vertices {}, {}, {} {}, zero area ({count} such \
         triangles); remove zero-area triangles and remesh or repair the surface (e.g. MeshLab \
         'Remove Zero Area Faces' or meshfix)",
        vertices[0], vertices[1], vertices[2],
        if vertices[0] == vertices[1] || vertices[1] == vertices[2] || vertices[0] == vertices[2] {
            "repeat a vertex"
        } else {
            "are collinear"
        }
    )]
    Degenerate {
        /// The first degenerate triangle.
        triangle: usize,
        /// Its vertex indices.
        vertices: [usize; 3],
        /// Number of degenerate triangles.
        count: usize,
    },
    /// Consistently oriented, but the normals point inward.
    #[error(
        "the surface is oriented inward (enclosed volume {volume:.6e} is negative); flip every \
         triangle's vertex order so that normals point out of the enclosed region"
    )]
    Inward {
        /// The (negative) enclosed volume.
        volume: f64,
    },
    /// Triangles cross each other: the surface intersects itself or holds overlapping shells.
    #[error(
        "the surface intersects itself: {count} pairs of triangles cross or overlap (e.g. \
         triangles {} and {}); a skull must be one closed shell that does not cross itself: \
         repair or remesh it (e.g. MeshLab 'Select Self Intersecting Faces', meshfix or \
         pymeshfix) and keep a single shell where two overlap",
        example.first, example.second
    )]
    SelfIntersecting {
        /// Number of intersecting pairs.
        count: usize,
        /// One intersecting pair.
        example: SelfIntersection,
    },
}

impl TriSurface {
    /// A surface from vertices and triangles.
    pub fn new(vertices: Vec<Point3<f64>>, triangles: Vec<[usize; 3]>) -> Self {
        TriSurface { vertices, triangles }
    }

    /// The three corner points of triangle `t`.
    pub fn corners(&self, t: usize) -> [Point3<f64>; 3] {
        let [a, b, c] = self.triangles[t];
        [self.vertices[a], self.vertices[b], self.vertices[c]]
    }

    /// Right-hand normal of triangle `t` scaled by twice its area.
    pub fn area_normal(&self, t: usize) -> Vector3<f64> {
        let [a, b, c] = self.corners(t);
        (b - a).cross(&(c - a))
    }

    /// Enclosed volume by the divergence theorem: positive for a closed outward surface.
    pub fn signed_volume(&self) -> f64 {
        // Relative to the centroid of the vertices for accuracy far from the origin.
        let n = self.vertices.len().max(1) as f64;
        let o = self.vertices.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
        self.triangles
            .iter()
            .map(|&[a, b, c]| {
                let (a, b, c) = (
                    self.vertices[a].coords - o,
                    self.vertices[b].coords - o,
                    self.vertices[c].coords - o,
                );
                a.dot(&b.cross(&c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Total area.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len()).map(|t| 0.5 * self.area_normal(t).norm()).sum()
    }

    /// Bounding box `(min, max)`, `None` without vertices.
    pub fn bounding_box(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        crate::mesh::bounding_box(&self.vertices)
    }

    /// Reverses every triangle (turns an inward surface outward).
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Index range check: the first triangle that refers to a missing vertex.
    fn check_indices(&self) -> Result<(), SurfaceError> {
        let count = self.vertices.len();
        for (triangle, t) in self.triangles.iter().enumerate() {
            if let Some(&vertex) = t.iter().find(|&&v| v >= count) {
                return Err(SurfaceError::VertexOutOfRange { triangle, vertex, count });
            }
        }
        Ok(())
    }

    /// Builds the adjacency. Fails only when a triangle refers to a missing vertex; all
    /// other defects are recorded in the topology (see [`TriSurface::check`]).
    pub fn topology(&self) -> Result<SurfaceTopology, SurfaceError> {
        self.check_indices()?;
        let nv = self.vertices.len();
        let nf = self.triangles.len();

        // Node -> faces (CSR).
        let mut node_face_offsets = vec![0usize; nv + 1];
        for t in &self.triangles {
            for &v in t {
                node_face_offsets[v + 1] += 1;
            }
        }
        for i in 0..nv {
            node_face_offsets[i + 1] += node_face_offsets[i];
        }
        let mut fill = node_face_offsets.clone();
        let mut node_faces = vec![0usize; node_face_offsets[nv]];
        for (f, t) in self.triangles.iter().enumerate() {
            for &v in t {
                node_faces[fill[v]] = f;
                fill[v] += 1;
            }
        }

        // Edges, with their faces and the direction in which each face traverses them.
        let mut edge_index: HashMap<(usize, usize), usize> = HashMap::with_capacity(nf * 3 / 2);
        let mut edges: Vec<Edge> = Vec::with_capacity(nf * 3 / 2);
        let mut first_dir: Vec<bool> = Vec::with_capacity(nf * 3 / 2);
        let mut face_edges = vec![[0usize; 3]; nf];
        let mut misoriented = Vec::new();
        for (f, t) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                let forward = a < b;
                let e = *edge_index.entry(key).or_insert_with(|| {
                    edges.push(Edge { nodes: [key.0, key.1], faces: [None, None], face_count: 0 });
                    first_dir.push(forward);
                    edges.len() - 1
                });
                let edge = &mut edges[e];
                if edge.face_count < 2 {
                    edge.faces[edge.face_count] = Some(f);
                }
                if edge.face_count == 1 && first_dir[e] == forward {
                    misoriented.push(e);
                }
                edge.face_count += 1;
                face_edges[f][k] = e;
            }
        }

        // Node -> edges (CSR).
        let mut node_edge_offsets = vec![0usize; nv + 1];
        for e in &edges {
            node_edge_offsets[e.nodes[0] + 1] += 1;
            node_edge_offsets[e.nodes[1] + 1] += 1;
        }
        for i in 0..nv {
            node_edge_offsets[i + 1] += node_edge_offsets[i];
        }
        let mut fill = node_edge_offsets.clone();
        let mut node_edges = vec![0usize; node_edge_offsets[nv]];
        for (i, e) in edges.iter().enumerate() {
            for &v in &e.nodes {
                node_edges[fill[v]] = i;
                fill[v] += 1;
            }
        }

        let face_normals = (0..nf)
            .map(|t| self.area_normal(t).try_normalize(0.0).unwrap_or_else(Vector3::zeros))
            .collect();
        let boundary_edges = (0..edges.len()).filter(|&e| edges[e].face_count == 1).collect();
        let non_manifold_edges = (0..edges.len()).filter(|&e| edges[e].face_count > 2).collect();
        misoriented.sort_unstable();
        misoriented.dedup();

        let mut topo = SurfaceTopology {
            node_face_offsets,
            node_faces,
            node_edge_offsets,
            node_edges,
            edges,
            face_edges,
            face_normals,
            boundary_edges,
            non_manifold_edges,
            misoriented_edges: misoriented,
            non_manifold_vertices: Vec::new(),
            unused_vertices: Vec::new(),
        };
        for v in 0..nv {
            let faces = topo.faces_of_node(v);
            if faces.is_empty() {
                topo.unused_vertices.push(v);
            } else if fan_count(&topo, faces) > 1 {
                topo.non_manifold_vertices.push(v);
            }
        }
        Ok(topo)
    }

    /// Triangles with zero area: a repeated vertex index, or an area below `1e-14·d²` where
    /// `d` is the diagonal of the bounding box (collinear vertices up to rounding).
    ///
    /// Indices must be in range (see [`TriSurface::topology`]).
    pub fn degenerate_triangles(&self) -> Vec<usize> {
        let tol = self.zero_area_tolerance();
        (0..self.triangles.len()).filter(|&t| self.is_degenerate(t, tol)).collect()
    }

    /// The area below which a triangle counts as zero: `1e-14·d²`, `d` the bounding-box
    /// diagonal.
    pub(crate) fn zero_area_tolerance(&self) -> f64 {
        let scale = self
            .bounding_box()
            .map(|(lo, hi)| (hi - lo).norm())
            .filter(|d| *d > 0.0)
            .unwrap_or(1.0);
        1e-14 * scale * scale
    }

    /// Triangle `t` (indices in range) repeats a vertex or has an area of at most `tol`.
    pub(crate) fn is_degenerate(&self, t: usize, tol: f64) -> bool {
        let [a, b, c] = self.triangles[t];
        a == b || b == c || a == c || 0.5 * self.area_normal(t).norm() <= tol
    }
}

/// Number of edge-connected fans among the faces around one vertex.
fn fan_count(topo: &SurfaceTopology, faces: &[usize]) -> usize {
    // Tiny union-find over the vertex's faces (valence is small).
    let mut parent: Vec<usize> = (0..faces.len()).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for (i, &f) in faces.iter().enumerate() {
        for &e in &topo.face_edges[f] {
            for g in topo.edges[e].faces.iter().flatten() {
                if let Some(j) = faces.iter().position(|x| x == g) {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                    parent[a] = b;
                }
            }
        }
    }
    (0..faces.len()).filter(|&i| root(&mut parent, i) == i).count()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A regular octahedron of circumradius 1, outward oriented.
    pub(crate) fn octahedron() -> TriSurface {
        let v = vec![
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(-1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, -1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
            Point3::new(0.0, 0.0, -1.0),
        ];
        let t = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        TriSurface::new(v, t)
    }

    #[test]
    fn octahedron_is_closed_outward_with_euler_two() {
        let s = octahedron();
        let c = s.check().unwrap();
        assert!(c.is_closed_outward(), "{c:?}");
        assert_eq!((c.edges, c.euler_characteristic, c.components), (12, 2, 1));
        // Octahedron of circumradius 1: volume 4/3 exactly.
        approx::assert_relative_eq!(c.signed_volume, 4.0 / 3.0, epsilon = 1e-14);
        // Surface area: 8 equilateral triangles of side sqrt(2): 8 * sqrt(3)/4 * 2.
        approx::assert_relative_eq!(s.area(), 4.0 * 3f64.sqrt(), epsilon = 1e-14);
        assert!(s.require_closed_outward().is_ok());
    }

    #[test]
    fn node_and_edge_normals_are_sums_of_face_normals() {
        let s = octahedron();
        let t = s.topology().unwrap();
        // By symmetry the normal at vertex +x is +x, and the normal of edge (+x,+z) is
        // along (1,0,1)/sqrt(2).
        approx::assert_relative_eq!(t.node_normal(0), Vector3::x(), epsilon = 1e-15);
        let e = t.edges.iter().position(|e| e.nodes == [0, 4]).unwrap();
        let expect = Vector3::new(1.0, 0.0, 1.0).normalize();
        approx::assert_relative_eq!(t.edge_normal(e), expect, epsilon = 1e-15);
        assert_eq!(t.faces_of_node(4).len(), 4);
        assert_eq!(t.edges_of_node(4).len(), 4);
    }

    #[test]
    fn inward_surface_is_rejected_with_its_volume() {
        let mut s = octahedron();
        s.flip();
        match s.require_closed_outward() {
            Err(SurfaceError::Inward { volume }) => {
                approx::assert_relative_eq!(volume, -4.0 / 3.0, epsilon = 1e-14)
            }
            other => panic!("expected Inward, got {other:?}"),
        }
    }

    #[test]
    fn open_surface_names_a_boundary_edge() {
        let mut s = octahedron();
        s.triangles.pop(); // remove [0, 3, 5]
        let err = s.require_closed_outward().unwrap_err();
        match err {
            SurfaceError::Open { count, example } => {
                assert_eq!(count, 3);
                assert!([[0, 3], [3, 5], [0, 5]].contains(&example), "{example:?}");
            }
            other => panic!("expected Open, got {other:?}"),
        }
    }

    #[test]
    fn one_flipped_triangle_is_inconsistent() {
        let mut s = octahedron();
        s.triangles[0].swap(1, 2);
        let c = s.check().unwrap();
        assert_eq!(c.misoriented_edges, 3);
        assert!(matches!(s.require_closed_outward(), Err(SurfaceError::Inconsistent { .. })));
    }

    #[test]
    fn two_octahedra_touching_at_a_vertex_are_non_manifold() {
        let a = octahedron();
        // Second octahedron shifted by +2 in x shares vertex (1,0,0) with the first.
        let mut v = a.vertices.clone();
        let off = v.len();
        v.extend(a.vertices.iter().map(|p| p + Vector3::new(2.0, 0.0, 0.0)));
        let mut t = a.triangles.clone();
        // Vertex 1 of the copy is (1,0,0): replace it by vertex 0 of the first.
        t.extend(a.triangles.iter().map(|tri| tri.map(|i| if i == 1 { 0 } else { i + off })));
        let s = TriSurface::new(v, t);
        let c = s.check().unwrap();
        assert_eq!(c.non_manifold_vertices, 1);
        assert_eq!(c.unused_vertices, 1); // the copy's own (1,0,0)
        assert!(matches!(
            s.require_closed_outward(),
            Err(SurfaceError::NonManifold { example: 0, .. })
        ));
    }

    #[test]
    fn degenerate_triangles_are_named_not_reported_as_holes() {
        // A repeated vertex index: the old check saw the edge (0, 0) as a hole.
        let mut s = octahedron();
        s.triangles.push([0, 0, 2]);
        let e = s.require_closed_outward().unwrap_err();
        assert_eq!(e, SurfaceError::Degenerate { triangle: 8, vertices: [0, 0, 2], count: 1 });
        let msg = e.to_string();
        assert!(
            msg.starts_with(
                "triangle 8 is degenerate: vertices 0, 0, 2 repeat a vertex, zero area"
            ),
            "{msg}"
        );
        assert!(msg.contains("remesh"), "{msg}");
        // Three collinear vertices: split the edge 0–2 at its midpoint into a sliver.
        let mut s = octahedron();
        s.vertices.push(Point3::new(0.5, 0.5, 0.0));
        // Triangles [0, 2, 4] and [2, 0, 5] use edge 0–2; route both through vertex 6.
        s.triangles[0] = [0, 6, 4];
        s.triangles.push([6, 2, 4]);
        s.triangles[4] = [2, 6, 5];
        s.triangles.push([6, 0, 5]);
        assert!(s.require_closed_outward().is_ok());
        s.triangles.push([0, 6, 2]);
        s.triangles.push([0, 2, 6]);
        assert_eq!(s.degenerate_triangles(), [10, 11]);
        let e = s.require_closed_outward().unwrap_err();
        assert!(
            e.to_string().starts_with(
                "triangle 10 is degenerate: vertices 0, 6, 2 are collinear, zero area (2 such"
            ),
            "{e}"
        );
        assert_eq!(s.check().unwrap().degenerate_triangles, 2);
    }

    #[test]
    fn out_of_range_vertex_is_an_error_not_a_panic() {
        let mut s = octahedron();
        s.triangles[3] = [0, 1, 99];
        assert_eq!(
            s.topology().unwrap_err(),
            SurfaceError::VertexOutOfRange { triangle: 3, vertex: 99, count: 6 }
        );
    }
}
