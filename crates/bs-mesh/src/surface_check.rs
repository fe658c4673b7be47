//! The checks a surface must pass to be an obstacle (a skull): counts of what is wrong
//! ([`TriSurface::check`]) and the first problem with its fix
//! ([`TriSurface::require_closed_outward`]). They sit above the topology (`surface`) and the
//! self-intersection search (`self_intersection`), which both read the surface.

use crate::self_intersection::SelfIntersection;
use crate::surface::{SurfaceError, SurfaceTopology, TriSurface};

/// The outcome of the closedness, manifoldness and orientation checks.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceCheck {
    /// Number of vertices.
    pub vertices: usize,
    /// Number of triangles.
    pub triangles: usize,
    /// Number of undirected edges.
    pub edges: usize,
    /// Edges with one face.
    pub boundary_edges: usize,
    /// Edges with three or more faces.
    pub non_manifold_edges: usize,
    /// Vertices whose faces do not form one fan.
    pub non_manifold_vertices: usize,
    /// Edges traversed in the same direction by both faces.
    pub misoriented_edges: usize,
    /// Triangles with (numerically) zero area.
    pub degenerate_triangles: usize,
    /// Pairs of triangles that cross or overlap beyond a shared vertex or edge (see
    /// [`TriSurface::self_intersections`]); empty for a valid skull.
    pub self_intersections: Vec<SelfIntersection>,
    /// Vertices used by no triangle.
    pub unused_vertices: usize,
    /// Connected components (by shared edges).
    pub components: usize,
    /// Euler characteristic V − E + F over used vertices (2 for a sphere-like surface).
    pub euler_characteristic: i64,
    /// Enclosed volume by the divergence theorem (positive when outward oriented; only
    /// meaningful for a closed surface).
    pub signed_volume: f64,
}

impl SurfaceCheck {
    /// Closed (no boundary edges) and manifold (edges with two faces, vertices with one fan).
    pub fn is_closed_manifold(&self) -> bool {
        self.boundary_edges == 0 && self.non_manifold_edges == 0 && self.non_manifold_vertices == 0
    }

    /// Closed, manifold, consistently oriented, with positive enclosed volume.
    pub fn is_closed_outward(&self) -> bool {
        self.is_closed_manifold() && self.misoriented_edges == 0 && self.signed_volume > 0.0
    }
}

impl TriSurface {
    /// Runs every check and counts what it finds.
    pub fn check(&self) -> Result<SurfaceCheck, SurfaceError> {
        let topo = self.topology()?;
        let degenerate_triangles = self.degenerate_triangles().len();
        let used = self.vertices.len() - topo.unused_vertices.len();
        Ok(SurfaceCheck {
            vertices: self.vertices.len(),
            triangles: self.triangles.len(),
            edges: topo.edges.len(),
            boundary_edges: topo.boundary_edges.len(),
            non_manifold_edges: topo.non_manifold_edges.len(),
            non_manifold_vertices: topo.non_manifold_vertices.len(),
            misoriented_edges: topo.misoriented_edges.len(),
            degenerate_triangles,
            self_intersections: self.self_intersections(),
            unused_vertices: topo.unused_vertices.len(),
            components: components(self.triangles.len(), &topo),
            euler_characteristic: used as i64 - topo.edges.len() as i64
                + self.triangles.len() as i64,
            signed_volume: self.signed_volume(),
        })
    }

    /// Requires a closed, manifold, consistently and outward-oriented surface without
    /// zero-area triangles that does not intersect itself (what a skull must be) and returns
    /// its topology; otherwise the first problem with its fix.
    pub fn require_closed_outward(&self) -> Result<SurfaceTopology, SurfaceError> {
        if self.triangles.is_empty() {
            return Err(SurfaceError::Empty);
        }
        let topo = self.topology()?;
        // First: a repeated vertex would otherwise show up as a bogus open edge (v, v).
        let degenerate = self.degenerate_triangles();
        if let Some(&triangle) = degenerate.first() {
            return Err(SurfaceError::Degenerate {
                triangle,
                vertices: self.triangles[triangle],
                count: degenerate.len(),
            });
        }
        if let Some(&e) = topo.boundary_edges.first() {
            return Err(SurfaceError::Open {
                count: topo.boundary_edges.len(),
                example: topo.edges[e].nodes,
            });
        }
        let nm = topo.non_manifold_edges.len() + topo.non_manifold_vertices.len();
        if nm > 0 {
            let example = topo
                .non_manifold_vertices
                .first()
                .copied()
                .or_else(|| topo.non_manifold_edges.first().map(|&e| topo.edges[e].nodes[0]))
                .unwrap_or(0);
            return Err(SurfaceError::NonManifold { count: nm, example });
        }
        if let Some(&e) = topo.misoriented_edges.first() {
            return Err(SurfaceError::Inconsistent {
                count: topo.misoriented_edges.len(),
                example: topo.edges[e].nodes,
            });
        }
        let volume = self.signed_volume();
        if volume <= 0.0 {
            return Err(SurfaceError::Inward { volume });
        }
        let crossing = self.self_intersections();
        if let Some(&example) = crossing.first() {
            return Err(SurfaceError::SelfIntersecting { count: crossing.len(), example });
        }
        Ok(topo)
    }
}

/// Number of edge-connected components of the faces.
fn components(nf: usize, topo: &SurfaceTopology) -> usize {
    let mut seen = vec![false; nf];
    let mut count = 0;
    let mut stack = Vec::new();
    for start in 0..nf {
        if seen[start] {
            continue;
        }
        count += 1;
        seen[start] = true;
        stack.push(start);
        while let Some(f) = stack.pop() {
            for &e in &topo.face_edges[f] {
                for &g in topo.edges[e].faces.iter().flatten() {
                    if !seen[g] {
                        seen[g] = true;
                        stack.push(g);
                    }
                }
            }
        }
    }
    count
}
