//! Typed errors for bad master (skull) surfaces and bad slave input.

/// Why a master surface or a slave set cannot be used for contact.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactError {
    /// The surface has no triangles.
    #[error("skull surface has no triangles; give a closed, outward-oriented triangle surface")]
    Empty,
    /// A triangle names a vertex that does not exist.
    #[error(
        "skull triangle {triangle} names vertex {vertex}, but the surface has only {vertex_count} vertices; fix the triangle list"
    )]
    VertexOutOfRange {
        /// Triangle index (0-based).
        triangle: usize,
        /// The offending vertex index.
        vertex: usize,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("skull vertex {vertex} has a non-finite coordinate; fix the surface file")]
    NonFinite {
        /// Vertex index (0-based).
        vertex: usize,
    },
    /// A triangle has zero area (repeated or collinear vertices).
    #[error(
        "skull triangle {triangle} {vertices:?} has zero area; remove it or remesh the skull (degenerate triangles have no normal)"
    )]
    DegenerateTriangle {
        /// Triangle index.
        triangle: usize,
        /// Its vertices.
        vertices: [usize; 3],
    },
    /// An edge belongs to only one triangle: the surface has a hole.
    #[error(
        "skull surface is open: edge ({a}, {b}) belongs to only triangle {triangle}; close the hole (the cavity must be watertight)"
    )]
    OpenEdge {
        /// Edge end.
        a: usize,
        /// Edge end.
        b: usize,
        /// The single triangle on it.
        triangle: usize,
    },
    /// An edge belongs to more than two triangles.
    #[error(
        "skull surface is non-manifold: edge ({a}, {b}) belongs to {count} triangles {triangles:?}; split or remesh it so every edge has exactly two triangles"
    )]
    NonManifoldEdge {
        /// Edge end.
        a: usize,
        /// Edge end.
        b: usize,
        /// Number of triangles on the edge.
        count: usize,
        /// The triangles on the edge.
        triangles: Vec<usize>,
    },
    /// Two triangles traverse their shared edge in the same direction.
    #[error(
        "skull orientation is inconsistent: triangles {t1} and {t2} traverse edge ({a}, {b}) in the same direction; flip one of them (all triangles must be counter-clockwise seen from outside)"
    )]
    InconsistentOrientation {
        /// Edge end.
        a: usize,
        /// Edge end.
        b: usize,
        /// First triangle.
        t1: usize,
        /// Second triangle.
        t2: usize,
    },
    /// The triangles around a vertex do not form a single fan (two surface sheets touch at
    /// a vertex).
    #[error(
        "skull surface is non-manifold at vertex {vertex}: its triangles form {fans} separate fans; separate the sheets (duplicate the vertex) or remesh"
    )]
    NonManifoldVertex {
        /// Vertex index.
        vertex: usize,
        /// Number of separate fans.
        fans: usize,
    },
    /// The enclosed signed volume is not positive: triangles are clockwise seen from outside.
    #[error(
        "skull surface is inward-oriented (signed volume {volume:e} ≤ 0); flip every triangle so normals point out of the cavity"
    )]
    InwardOriented {
        /// The signed enclosed volume.
        volume: f64,
    },
    /// A slave node index is out of range of the positions array.
    #[error("slave node {node} is out of range: the mesh has {node_count} nodes")]
    SlaveOutOfRange {
        /// The slave index.
        node: usize,
        /// Number of positions.
        node_count: usize,
    },
    /// A parameter is invalid.
    #[error("invalid contact parameter: {0}")]
    InvalidParameter(String),
}
