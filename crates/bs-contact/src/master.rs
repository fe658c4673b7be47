//! The master (skull) surface with everything the handlers precompute: validated topology,
//! edges with their two faces, node→faces and node→edges adjacency, face / edge / node
//! normals, angle bisectors, node radii.

use std::collections::HashMap;

use bs_mesh::TriSurface;
use nalgebra::{Point3, Vector3};

use crate::ContactError;
use crate::geometry::{TriRegion, closest_point_triangle, corner_angle, triangle_normal};
use crate::query::{Feature, Projection};

/// How the normal at a node is formed from the normals of the faces around it.
///
/// The paper defines edge and node normals as "the sum of the normal vectors of adjacent
/// faces". At an edge both readings below coincide (two faces, equal weights). At a node
/// the plain sum of unit normals depends on how the surface is triangulated (a flat face
/// split into many slivers at the node counts many times; see the cube-corner test) and is
/// not guaranteed to give the right inside/outside sign at non-convex vertices; weighting
/// each face normal by the face's angle at the node (Bærentzen & Aanæs, "Signed distance
/// computation using the angle weighted pseudonormal", IEEE TVCG 2005) is independent of the
/// triangulation and proven to give the right sign for every closest point. Both are sums of
/// adjacent face normals; the angle-weighted one is the default, and it agrees with parry's
/// inside test on every query of our tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NodeNormalRule {
    /// Sum of the unit normals of the faces around the node, each weighted by its corner
    /// angle at the node (default; exact inside/outside verdict).
    #[default]
    AngleWeighted,
    /// Plain sum of the unit normals of the faces around the node (the paper's literal
    /// wording).
    PlainSum,
}

/// A validated, outward-oriented closed triangle surface with precomputed adjacency and
/// normals. Built once per skull and shared by all handlers (`Arc<MasterSurface>`); read
/// through its accessors, so that what was validated stays valid.
#[derive(Debug, Clone)]
pub struct MasterSurface {
    /// Vertex coordinates.
    vertices: Vec<Point3<f64>>,
    /// Triangles, counter-clockwise seen from outside.
    triangles: Vec<[u32; 3]>,
    /// Unique edges `[a, b]` with `a < b`.
    edges: Vec<[u32; 2]>,
    /// The two faces of each edge.
    edge_faces: Vec<[u32; 2]>,
    /// For each face, the edge index of its sides `v0→v1`, `v1→v2`, `v2→v0`.
    face_edges: Vec<[u32; 3]>,
    /// Unit outward normal of each face.
    face_normals: Vec<Vector3<f64>>,
    /// Outward edge normal: sum of the unit normals of its two faces.
    edge_normals: Vec<Vector3<f64>>,
    /// Outward node normal (see [`NodeNormalRule`]).
    node_normals: Vec<Vector3<f64>>,
    /// Unit bisector of the angle at each corner of each face.
    bisectors: Vec<[Vector3<f64>; 3]>,
    /// Radius of influence of each node: the longest edge containing it (0 if unused).
    node_radius: Vec<f64>,
    /// CSR offsets of node→faces.
    node_faces_start: Vec<u32>,
    /// CSR list of node→faces.
    node_faces: Vec<u32>,
    /// CSR offsets of node→edges.
    node_edges_start: Vec<u32>,
    /// CSR list of node→edges.
    node_edges: Vec<u32>,
    /// Longest edge length.
    max_edge: f64,
    /// Longest projection of an edge on each axis.
    max_edge_projection: Vector3<f64>,
    /// Diagonal of the bounding box (the model size used for tolerances).
    size: f64,
    /// The node normal rule used.
    node_rule: NodeNormalRule,
}

impl MasterSurface {
    /// Validates `surface` (closed, edge- and vertex-manifold, consistently and outward
    /// oriented, no degenerate triangles, finite coordinates) and precomputes adjacency and
    /// normals with the default (angle-weighted) node normal rule.
    pub fn new(surface: &TriSurface) -> Result<Self, ContactError> {
        Self::with_rule(surface, NodeNormalRule::default())
    }

    /// As [`new`](Self::new) with an explicit node normal rule.
    pub fn with_rule(
        surface: &TriSurface,
        node_rule: NodeNormalRule,
    ) -> Result<Self, ContactError> {
        let nv = surface.vertices.len();
        let triangles = checked_triangles(surface)?;
        let (edges, edge_faces, face_edges) = edge_topology(&triangles)?;
        let verts = surface.vertices.clone();
        let p = |i: u32| &verts[i as usize];

        // Node → faces, node → edges (CSR).
        let (node_faces_start, node_faces) = csr(
            nv,
            triangles
                .iter()
                .enumerate()
                .flat_map(|(t, tri)| tri.iter().map(move |&v| (v, t as u32))),
        );
        let (node_edges_start, node_edges) = csr(
            nv,
            edges.iter().enumerate().flat_map(|(e, ab)| ab.iter().map(move |&v| (v, e as u32))),
        );
        check_vertex_fans(&triangles, &node_faces_start, &node_faces)?;

        // Outward orientation: signed enclosed volume.
        let volume: f64 = triangles
            .iter()
            .map(|t| p(t[0]).coords.dot(&p(t[1]).coords.cross(&p(t[2]).coords)) / 6.0)
            .sum();
        if volume.is_nan() || volume <= 0.0 {
            return Err(ContactError::InwardOriented { volume });
        }

        let face_normals: Vec<Vector3<f64>> =
            triangles.iter().map(|t| triangle_normal(p(t[0]), p(t[1]), p(t[2])).0).collect();
        let edge_normals: Vec<Vector3<f64>> = edge_faces
            .iter()
            .map(|f| face_normals[f[0] as usize] + face_normals[f[1] as usize])
            .collect();
        let (node_normals, bisectors) =
            corner_normals(&verts, &triangles, &face_normals, node_rule);
        let extent = edge_extent(&verts, &edges);
        let (lo, hi) = bounds(verts.iter());
        let size = (hi - lo).norm();

        Ok(Self {
            vertices: verts,
            triangles,
            edges,
            edge_faces,
            face_edges,
            face_normals,
            edge_normals,
            node_normals,
            bisectors,
            node_radius: extent.node_radius,
            node_faces_start,
            node_faces,
            node_edges_start,
            node_edges,
            max_edge: extent.max_edge,
            max_edge_projection: extent.max_edge_projection,
            size,
            node_rule,
        })
    }

    /// Vertex coordinates.
    #[inline]
    pub fn vertices(&self) -> &[Point3<f64>] {
        &self.vertices
    }

    /// Triangles, counter-clockwise seen from outside.
    #[inline]
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Unique edges `[a, b]` with `a < b`.
    #[inline]
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// The two faces of each edge.
    #[inline]
    pub fn edge_faces(&self) -> &[[u32; 2]] {
        &self.edge_faces
    }

    /// For each face, the edge index of its sides `v0→v1`, `v1→v2`, `v2→v0`.
    #[inline]
    pub fn face_edges(&self) -> &[[u32; 3]] {
        &self.face_edges
    }

    /// Unit outward normal of each face.
    #[inline]
    pub fn face_normals(&self) -> &[Vector3<f64>] {
        &self.face_normals
    }

    /// Outward edge normal: sum of the unit normals of its two faces.
    #[inline]
    pub fn edge_normals(&self) -> &[Vector3<f64>] {
        &self.edge_normals
    }

    /// Outward node normal (see [`NodeNormalRule`]).
    #[inline]
    pub fn node_normals(&self) -> &[Vector3<f64>] {
        &self.node_normals
    }

    /// Unit bisector of the angle at each corner of each face.
    #[inline]
    pub fn bisectors(&self) -> &[[Vector3<f64>; 3]] {
        &self.bisectors
    }

    /// Radius of influence of each node: the longest edge containing it (0 if unused).
    #[inline]
    pub fn node_radius(&self) -> &[f64] {
        &self.node_radius
    }

    /// Longest edge length.
    #[inline]
    pub fn max_edge(&self) -> f64 {
        self.max_edge
    }

    /// Longest projection of an edge on each axis.
    #[inline]
    pub fn max_edge_projection(&self) -> &Vector3<f64> {
        &self.max_edge_projection
    }

    /// Diagonal of the bounding box (the model size used for tolerances).
    #[inline]
    pub fn size(&self) -> f64 {
        self.size
    }

    /// The node normal rule used.
    #[inline]
    pub fn node_rule(&self) -> NodeNormalRule {
        self.node_rule
    }

    /// Faces containing node `v`.
    #[inline]
    pub fn faces_of(&self, v: u32) -> &[u32] {
        &self.node_faces[self.node_faces_start[v as usize] as usize
            ..self.node_faces_start[v as usize + 1] as usize]
    }

    /// Edges containing node `v`.
    #[inline]
    pub fn edges_of(&self, v: u32) -> &[u32] {
        &self.node_edges[self.node_edges_start[v as usize] as usize
            ..self.node_edges_start[v as usize + 1] as usize]
    }

    /// Whether node `v` belongs to at least one triangle.
    #[inline]
    pub fn is_used(&self, v: u32) -> bool {
        self.node_faces_start[v as usize] != self.node_faces_start[v as usize + 1]
    }

    /// The outward normal used for the inside/outside verdict at a feature.
    #[inline]
    pub fn normal(&self, f: Feature) -> &Vector3<f64> {
        match f {
            Feature::Node(v) => &self.node_normals[v as usize],
            Feature::Edge(e) => &self.edge_normals[e as usize],
            Feature::Face(t) => &self.face_normals[t as usize],
        }
    }

    /// Global feature for a local triangle region.
    #[inline]
    pub fn feature_of(&self, face: u32, region: TriRegion) -> Feature {
        match region {
            TriRegion::Vertex(k) => Feature::Node(self.triangles[face as usize][k as usize]),
            TriRegion::Edge(k) => Feature::Edge(self.face_edges[face as usize][k as usize]),
            TriRegion::Face => Feature::Face(face),
        }
    }

    /// Outside verdict of the paper: `RP · n > 0` with the outward normal at the feature.
    #[inline]
    pub fn is_outside(&self, p: &Point3<f64>, r: &Point3<f64>, f: Feature) -> bool {
        (p - r).dot(self.normal(f)) > 0.0
    }

    /// The [`Projection`] of `p` on the surface point `r` of feature `f` at squared distance
    /// `d2 = |PR|²`, with the paper's verdict at `r`.
    #[inline]
    pub(crate) fn projection(
        &self,
        p: &Point3<f64>,
        r: Point3<f64>,
        d2: f64,
        f: Feature,
    ) -> Projection {
        let outside = self.is_outside(p, &r, f);
        let dist = d2.sqrt();
        Projection {
            point: r,
            signed_distance: if outside { -dist } else { dist },
            outside,
            feature: Some(f),
        }
    }

    /// The exact closest point of `p` among the triangles `faces` (exact point–triangle
    /// projection on each, the first one offered wins on exact ties), with its feature and
    /// the paper's verdict there. `None` when `faces` is empty or `p` is not finite. Handlers
    /// that know where the closest face must be (a grid box, a BVH leaf and its neighbours)
    /// pass those faces; [`project_exact`](Self::project_exact) passes them all.
    pub fn project_on_faces(
        &self,
        p: &Point3<f64>,
        faces: impl IntoIterator<Item = u32>,
    ) -> Option<Projection> {
        let mut best: Option<(f64, Point3<f64>, Feature)> = None;
        for t in faces {
            let tri = self.triangles[t as usize];
            let (q, region) = closest_point_triangle(
                p,
                &self.vertices[tri[0] as usize],
                &self.vertices[tri[1] as usize],
                &self.vertices[tri[2] as usize],
            );
            let d2 = (q - p).norm_squared();
            if d2 < best.map_or(f64::INFINITY, |b| b.0) {
                best = Some((d2, q, self.feature_of(t, region)));
            }
        }
        best.map(|(d2, q, f)| self.projection(p, q, d2, f))
    }

    /// The exact closest point of the surface to `p` at any distance, with its feature and
    /// the paper's verdict: every face is tested (O(faces); the reference the handlers are
    /// tested against, and the exact fallback of the diagnostics). `None` for a non-finite
    /// point.
    pub fn project_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        if !p.coords.iter().all(|x| x.is_finite()) {
            return None;
        }
        self.project_on_faces(p, 0..self.triangles.len() as u32)
    }

    /// Signed volume enclosed by the surface (positive for outward orientation).
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let (a, b, c) = (
                    &self.vertices[t[0] as usize],
                    &self.vertices[t[1] as usize],
                    &self.vertices[t[2] as usize],
                );
                a.coords.dot(&b.coords.cross(&c.coords)) / 6.0
            })
            .sum()
    }
}

/// Axis-aligned bounds of a point set.
pub(crate) fn bounds<'a>(pts: impl Iterator<Item = &'a Point3<f64>>) -> (Point3<f64>, Point3<f64>) {
    let mut lo = Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut hi = Point3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in pts {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// The surface's triangles as `u32` indices, refused when a vertex is not finite, an index
/// points past the vertices or a triangle is degenerate.
fn checked_triangles(surface: &TriSurface) -> Result<Vec<[u32; 3]>, ContactError> {
    let nv = surface.vertices.len();
    if surface.triangles.is_empty() {
        return Err(ContactError::Empty);
    }
    for (i, v) in surface.vertices.iter().enumerate() {
        if !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()) {
            return Err(ContactError::NonFinite { vertex: i });
        }
    }
    let mut triangles = Vec::with_capacity(surface.triangles.len());
    for (t, tri) in surface.triangles.iter().enumerate() {
        for &v in tri {
            if v >= nv {
                return Err(ContactError::VertexOutOfRange {
                    triangle: t,
                    vertex: v,
                    vertex_count: nv,
                });
            }
        }
        let v = &surface.vertices;
        let (n, area) = triangle_normal(&v[tri[0]], &v[tri[1]], &v[tri[2]]);
        let scale =
            (v[tri[1]] - v[tri[0]]).norm_squared().max((v[tri[2]] - v[tri[0]]).norm_squared());
        if tri[0] == tri[1]
            || tri[1] == tri[2]
            || tri[0] == tri[2]
            || area <= 1e-14 * scale
            || n == Vector3::zeros()
        {
            return Err(ContactError::DegenerateTriangle { triangle: t, vertices: *tri });
        }
        triangles.push([tri[0] as u32, tri[1] as u32, tri[2] as u32]);
    }
    Ok(triangles)
}

/// Edges (sorted by their vertex pair), each edge's two faces and each face's three edges;
/// an edge with one face, two faces of the same orientation or more than two faces is
/// refused.
#[allow(clippy::type_complexity)]
fn edge_topology(
    triangles: &[[u32; 3]],
) -> Result<(Vec<[u32; 2]>, Vec<[u32; 2]>, Vec<[u32; 3]>), ContactError> {
    // Undirected edges with their faces and the direction each face runs them.
    let mut undirected: HashMap<(u32, u32), Vec<(u32, bool)>> =
        HashMap::with_capacity(triangles.len() * 2);
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            undirected.entry(key).or_default().push((t as u32, a < b));
        }
    }
    let mut keys: Vec<(u32, u32)> = undirected.keys().copied().collect();
    keys.sort_unstable();
    let mut edges = Vec::with_capacity(keys.len());
    let mut edge_faces = Vec::with_capacity(keys.len());
    let mut edge_index: HashMap<(u32, u32), u32> = HashMap::with_capacity(keys.len());
    for key in keys {
        let faces = &undirected[&key];
        match faces.len() {
            1 => {
                return Err(ContactError::OpenEdge {
                    a: key.0 as usize,
                    b: key.1 as usize,
                    triangle: faces[0].0 as usize,
                });
            }
            2 => {
                if faces[0].1 == faces[1].1 {
                    return Err(ContactError::InconsistentOrientation {
                        a: key.0 as usize,
                        b: key.1 as usize,
                        t1: faces[0].0 as usize,
                        t2: faces[1].0 as usize,
                    });
                }
            }
            n => {
                return Err(ContactError::NonManifoldEdge {
                    a: key.0 as usize,
                    b: key.1 as usize,
                    count: n,
                    triangles: faces.iter().map(|f| f.0 as usize).collect(),
                });
            }
        }
        edge_index.insert(key, edges.len() as u32);
        edges.push([key.0, key.1]);
        edge_faces.push([faces[0].0, faces[1].0]);
    }
    let face_edges: Vec<[u32; 3]> = triangles
        .iter()
        .map(|tri| {
            let mut fe = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                fe[k] = edge_index[&(a.min(b), a.max(b))];
            }
            fe
        })
        .collect();
    Ok((edges, edge_faces, face_edges))
}

/// A compressed row list of `(row, item)` pairs over `count` rows: row starts and items, in
/// the pairs' order within each row.
fn csr(count: usize, items: impl Iterator<Item = (u32, u32)>) -> (Vec<u32>, Vec<u32>) {
    let pairs: Vec<(u32, u32)> = items.collect();
    let mut start = vec![0u32; count + 1];
    for &(n, _) in &pairs {
        start[n as usize + 1] += 1;
    }
    for i in 0..count {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut list = vec![0u32; pairs.len()];
    for &(n, x) in &pairs {
        list[fill[n as usize] as usize] = x;
        fill[n as usize] += 1;
    }
    (start, list)
}

/// Vertex manifoldness: the faces around each vertex form one fan.
fn check_vertex_fans(
    triangles: &[[u32; 3]],
    node_faces_start: &[u32],
    node_faces: &[u32],
) -> Result<(), ContactError> {
    let mut half_edge: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            half_edge.insert((tri[k], tri[(k + 1) % 3]), t as u32);
        }
    }
    for v in 0..node_faces_start.len() - 1 {
        let faces = &node_faces[node_faces_start[v] as usize..node_faces_start[v + 1] as usize];
        if faces.is_empty() {
            continue;
        }
        // Walk around v: from face f with corner v, cross the edge (v, next) into the face
        // that contains the half-edge (next, v).
        let mut count = 0usize;
        let mut f = faces[0];
        loop {
            let tri = triangles[f as usize];
            let k = tri.iter().position(|&x| x as usize == v).unwrap_or(0);
            let next = tri[(k + 1) % 3];
            f = half_edge[&(next, v as u32)];
            count += 1;
            if f == faces[0] || count > faces.len() {
                break;
            }
        }
        if count != faces.len() {
            let fans = faces.len().div_ceil(count.max(1)).max(2);
            return Err(ContactError::NonManifoldVertex { vertex: v, fans });
        }
    }
    Ok(())
}

/// Node normals (face normals summed with the rule's corner weights) and each corner's unit
/// angle bisector.
#[allow(clippy::type_complexity)]
fn corner_normals(
    verts: &[Point3<f64>],
    triangles: &[[u32; 3]],
    face_normals: &[Vector3<f64>],
    node_rule: NodeNormalRule,
) -> (Vec<Vector3<f64>>, Vec<[Vector3<f64>; 3]>) {
    let p = |i: u32| &verts[i as usize];
    let mut node_normals = vec![Vector3::zeros(); verts.len()];
    let mut bisectors = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        let mut b = [Vector3::zeros(); 3];
        for k in 0..3 {
            let (c, u, w) = (p(tri[k]), p(tri[(k + 1) % 3]), p(tri[(k + 2) % 3]));
            let weight = match node_rule {
                NodeNormalRule::AngleWeighted => corner_angle(c, u, w),
                NodeNormalRule::PlainSum => 1.0,
            };
            node_normals[tri[k] as usize] += face_normals[t] * weight;
            let bis = (u - c).normalize() + (w - c).normalize();
            b[k] = bis.normalize();
        }
        bisectors.push(b);
    }
    (node_normals, bisectors)
}

/// How far the surface's edges reach: per node its longest edge, the longest edge and the
/// largest extent of an edge along each axis.
struct EdgeExtent {
    node_radius: Vec<f64>,
    max_edge: f64,
    max_edge_projection: Vector3<f64>,
}

fn edge_extent(verts: &[Point3<f64>], edges: &[[u32; 2]]) -> EdgeExtent {
    let p = |i: u32| &verts[i as usize];
    let mut node_radius = vec![0.0f64; verts.len()];
    let mut max_edge = 0.0f64;
    let mut max_edge_projection = Vector3::zeros();
    for e in edges {
        let d = p(e[1]) - p(e[0]);
        let len = d.norm();
        max_edge = max_edge.max(len);
        for k in 0..3 {
            max_edge_projection[k] = f64::max(max_edge_projection[k], d[k].abs());
        }
        for &v in e {
            node_radius[v as usize] = node_radius[v as usize].max(len);
        }
    }
    EdgeExtent { node_radius, max_edge, max_edge_projection }
}
