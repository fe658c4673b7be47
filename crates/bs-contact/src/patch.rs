//! Closest points on an open triangle patch that moves: the deformed exposed brain surface a
//! scan is fitted to. The patch's triangles are bucketed by their centroids on the paper's
//! uniform grid ([`BucketGrid`]), rebuilt for each configuration ([`Patch::update`]: the
//! grid of a few thousand centroids costs far less than one finite-element force
//! evaluation). A query finds the nearest centroid, which bounds the distance `d` to the
//! patch; every triangle within `d` has its centroid within `d + r` (`r` the largest
//! centroid-to-corner distance), so the exact closest point is the best of the triangles
//! whose centroids lie in that box.
//!
//! Unlike [`MasterSurface`](crate::MasterSurface) the patch need not be closed or
//! oriented consistently: it is a piece of a boundary, and a point may lie on either side.

use nalgebra::{Point3, Vector3};

use crate::geometry::{TriRegion, closest_point_triangle};
use crate::grid::BucketGrid;

/// The closest point of a [`Patch`] to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchPoint {
    /// The triangle it lies on (index into the patch's triangles).
    pub face: u32,
    /// The point.
    pub point: Point3<f64>,
    /// Its barycentric coordinates on the triangle's corners.
    pub bary: [f64; 3],
    /// Where on the triangle it lies (inside, on an edge, at a corner).
    pub region: TriRegion,
    /// Distance from the query point.
    pub distance: f64,
}

/// An open triangle patch with a bucket grid of its triangles (see the module
/// documentation).
#[derive(Debug, Clone)]
pub struct Patch {
    vertices: Vec<Point3<f64>>,
    triangles: Vec<[u32; 3]>,
    grid: BucketGrid,
    /// Largest distance from a triangle's centroid to its corners.
    reach: f64,
}

impl Patch {
    /// A patch of `triangles` (corner indices into `vertices`). Triangles naming a vertex
    /// that does not exist are dropped by the caller's validation, not here: they panic.
    pub fn new(vertices: Vec<Point3<f64>>, triangles: Vec<[u32; 3]>) -> Self {
        let grid = BucketGrid::new(&[], Vector3::repeat(1.0));
        let mut patch = Patch { vertices: Vec::new(), triangles, grid, reach: 0.0 };
        patch.update(&vertices);
        patch
    }

    /// Moves the patch's vertices to `vertices` (same count and order) and rebuilds the grid.
    pub fn update(&mut self, vertices: &[Point3<f64>]) {
        self.vertices.clear();
        self.vertices.extend_from_slice(vertices);
        let mut items = Vec::with_capacity(self.triangles.len());
        let (mut reach, mut edges, mut edge_sum) = (0.0f64, 0usize, 0.0f64);
        for (i, t) in self.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|k| self.vertices[k as usize]);
            let g = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            reach = reach.max((a - g).norm()).max((b - g).norm()).max((c - g).norm());
            edge_sum += (b - a).norm() + (c - b).norm() + (a - c).norm();
            edges += 3;
            items.push((i as u32, g));
        }
        let h = if edges > 0 { edge_sum / edges as f64 } else { 1.0 };
        self.grid = BucketGrid::new(&items, Vector3::repeat(h));
        self.reach = reach;
    }

    /// The patch's vertices.
    pub fn vertices(&self) -> &[Point3<f64>] {
        &self.vertices
    }

    /// The patch's triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The exact closest point of the patch to `p`, or `None` when the patch is empty, `p`
    /// is not finite or the patch is farther than `max_distance`. Ties go to the lowest
    /// triangle index.
    pub fn closest(&self, p: &Point3<f64>, max_distance: f64) -> Option<PatchPoint> {
        let nearest = self.grid.nearest(p, false)?;
        let bound = nearest.d2.sqrt();
        if bound - self.reach > max_distance {
            return None;
        }
        let mut best: Option<PatchPoint> = None;
        let radius = bound.min(max_distance) + self.reach;
        self.grid.for_each_in_box(p, radius, |id, _| {
            let t = self.triangles[id as usize];
            let [a, b, c] = t.map(|k| self.vertices[k as usize]);
            let (q, region) = closest_point_triangle(p, &a, &b, &c);
            let distance = (q - p).norm();
            let better = match &best {
                None => true,
                Some(o) => distance < o.distance || (distance == o.distance && id < o.face),
            };
            if better && distance <= max_distance {
                best = Some(PatchPoint {
                    face: id,
                    point: q,
                    bary: bary(&q, &a, &b, &c),
                    region,
                    distance,
                });
            }
        });
        best
    }
}

/// Barycentric coordinates of `q` (a point of the triangle's plane) on `[a, b, c]`; the
/// corners' for a degenerate triangle (zero area).
fn bary(q: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> [f64; 3] {
    let (e1, e2, d) = (b - a, c - a, q - a);
    let (d11, d12, d22) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
    let (d1, d2) = (d.dot(&e1), d.dot(&e2));
    let det = d11 * d22 - d12 * d12;
    if det <= f64::EPSILON * d11 * d22 {
        return [1.0, 0.0, 0.0];
    }
    let v = (d22 * d1 - d12 * d2) / det;
    let w = (d11 * d2 - d12 * d1) / det;
    [1.0 - v - w, v, w]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;
    use proptest::prelude::*;

    /// Every triangle tried: the reference the grid search must equal.
    fn brute(patch: &Patch, p: &Point3<f64>) -> (u32, f64) {
        let mut best = (u32::MAX, f64::INFINITY);
        for (i, t) in patch.triangles().iter().enumerate() {
            let [a, b, c] = t.map(|k| patch.vertices()[k as usize]);
            let d = (closest_point_triangle(p, &a, &b, &c).0 - p).norm();
            if d < best.1 {
                best = (i as u32, d);
            }
        }
        best
    }

    /// Half of a closed test surface: an open patch with a border.
    fn half_sphere() -> Patch {
        let s = shapes::sphere(400);
        let tris: Vec<[u32; 3]> = s
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&k| s.vertices[k].z >= -0.05))
            .map(|t| t.map(|k| k as u32))
            .collect();
        Patch::new(s.vertices.clone(), tris)
    }

    proptest! {
        /// The grid search finds the exact closest distance of the brute force, at any
        /// distance and from either side.
        #[test]
        fn closest_equals_brute_force(x in -2.0..2.0f64, y in -2.0..2.0f64, z in -2.0..2.0f64) {
            let patch = half_sphere();
            let p = Point3::new(x, y, z);
            let got = patch.closest(&p, f64::INFINITY).unwrap();
            let (_, d) = brute(&patch, &p);
            prop_assert!((got.distance - d).abs() <= 1e-12 * (1.0 + d), "{} vs {d}", got.distance);
            // The barycentric coordinates give the point back.
            let t = patch.triangles()[got.face as usize].map(|k| patch.vertices()[k as usize]);
            let q = t[0].coords * got.bary[0] + t[1].coords * got.bary[1] + t[2].coords * got.bary[2];
            prop_assert!((q - got.point.coords).norm() < 1e-12);
            prop_assert!(got.bary.iter().all(|&b| b > -1e-12 && b < 1.0 + 1e-12));
        }
    }

    #[test]
    fn a_patch_farther_than_the_limit_is_none_and_a_moved_patch_is_found_again() {
        let mut patch = half_sphere();
        let p = Point3::new(0.0, 0.0, 1.5);
        assert!(patch.closest(&p, 0.4).is_none());
        let d = patch.closest(&p, 0.6).unwrap().distance;
        assert!((d - 0.5).abs() < 0.02, "{d}");
        // Shift the patch up by 0.3: the same point is 0.2 away.
        let moved: Vec<_> =
            patch.vertices().iter().map(|v| v + Vector3::new(0.0, 0.0, 0.3)).collect();
        patch.update(&moved);
        let d = patch.closest(&p, 0.6).unwrap().distance;
        assert!((d - 0.2).abs() < 0.02, "{d}");
        assert!(Patch::new(Vec::new(), Vec::new()).closest(&p, 1.0).is_none());
    }
}
