//! Self-intersection of a triangle surface: pairs of triangles that cross or overlap.
//!
//! A rigid skull must be one closed shell that does not pass through itself; a surface that
//! folds through itself, or two overlapping closed shells, is closed, manifold and outward
//! by every topological check and yet no valid obstacle.
//!
//! **Pair test.** Orientation predicates only (signs of 3×3 determinants, as in
//! Guigue–Devillers): two closed triangles intersect iff an edge of one meets the other (a
//! closed segment–triangle test, with a 2D test in the plane for coplanar input). Triangles
//! that share mesh vertices are classified by what they share, so neighbours are never
//! reported for touching along their common edge or vertex:
//! * no shared vertex: any contact counts, touching included;
//! * one shared vertex `v`: they intersect beyond `v` iff the edge opposite `v` in one meets
//!   the other (the intersection is a segment from `v`, whose far end lies on such an edge);
//! * a shared edge: they intersect beyond it only when coplanar and folded onto each other
//!   (the two opposite vertices on the same side of the edge);
//! * three shared vertices: the same triangle twice, an overlap.
//!
//! Degenerate (zero-area) triangles and triangles with non-finite or out-of-range vertices
//! are skipped: [`TriSurface::require_closed_outward`] reports them first.
//!
//! **Acceleration.** A uniform bucket grid over the triangles' bounding boxes, with cells
//! about the size of a triangle and at most a few cells per triangle; each pair of
//! triangles is tested once, in the cell holding the low corner of the overlap of their
//! boxes.

use nalgebra::Point3;

pub use crate::surface::SelfIntersection;
use crate::surface::TriSurface;

type P = Point3<f64>;

/// Six times the signed volume of the tetrahedron `abcd`: positive when `d` is on the side
/// of `abc` its right-hand normal points to.
fn orient3d(a: &P, b: &P, c: &P, d: &P) -> f64 {
    (b - a).cross(&(c - a)).dot(&(d - a))
}

/// Relative size below which a point counts as on a plane: far above the rounding of the
/// determinants, far below any visible gap in a mesh.
const PLANE_EPS: f64 = 1e-12;

/// Which side of triangle `t`'s plane `p` is on (`orient3d` sign), snapped to exactly zero
/// when `p` is within rounding of the plane, so that nearly coplanar input takes the
/// coplanar path instead of trusting signs that are noise.
fn side(t: &[P; 3], p: &P) -> f64 {
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let d = n.dot(&(p - t[0]));
    let size = (p - t[0]).norm().max((t[1] - t[0]).norm()).max((t[2] - t[0]).norm());
    if d.abs() <= PLANE_EPS * n.norm() * size { 0.0 } else { d }
}

fn orient2d(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether `x` and `y` do not have the same strict sign (one is zero or they differ).
fn straddle(x: f64, y: f64) -> bool {
    !((x > 0.0 && y > 0.0) || (x < 0.0 && y < 0.0))
}

/// All three on one strict side (no contact possible).
fn one_side(d: [f64; 3]) -> bool {
    d.iter().all(|&x| x > 0.0) || d.iter().all(|&x| x < 0.0)
}

/// Projection onto the coordinate plane most parallel to triangle `t`.
fn projector(t: &[P; 3]) -> impl Fn(&P) -> [f64; 2] {
    let n = (t[1] - t[0]).cross(&(t[2] - t[0])).abs();
    let drop = if n.x >= n.y && n.x >= n.z {
        0
    } else if n.y >= n.z {
        1
    } else {
        2
    };
    move |p: &P| match drop {
        0 => [p.y, p.z],
        1 => [p.z, p.x],
        _ => [p.x, p.y],
    }
}

/// Closed 2D segments `pq` and `ab` meet.
fn segments_meet_2d(p: [f64; 2], q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    let (o1, o2) = (orient2d(p, q, a), orient2d(p, q, b));
    let (o3, o4) = (orient2d(a, b, p), orient2d(a, b, q));
    if o1 == 0.0 && o2 == 0.0 {
        // Collinear: overlapping intervals on both axes.
        return (0..2)
            .all(|k| p[k].min(q[k]) <= a[k].max(b[k]) && a[k].min(b[k]) <= p[k].max(q[k]));
    }
    straddle(o1, o2) && straddle(o3, o4)
}

/// Closed 2D point-in-triangle.
fn inside_2d(p: [f64; 2], t: [[f64; 2]; 3]) -> bool {
    let o = [orient2d(t[0], t[1], p), orient2d(t[1], t[2], p), orient2d(t[2], t[0], p)];
    o.iter().all(|&x| x >= 0.0) || o.iter().all(|&x| x <= 0.0)
}

/// A closed segment and a closed triangle in the same plane meet.
fn coplanar_segment_meets(p: &P, q: &P, t: &[P; 3]) -> bool {
    let proj = projector(t);
    let (p, q) = (proj(p), proj(q));
    let t2 = [proj(&t[0]), proj(&t[1]), proj(&t[2])];
    inside_2d(p, t2)
        || inside_2d(q, t2)
        || (0..3).any(|k| segments_meet_2d(p, q, t2[k], t2[(k + 1) % 3]))
}

/// The closed segment `pq` meets the closed, non-degenerate triangle `t`.
fn segment_meets_triangle(p: &P, q: &P, t: &[P; 3]) -> bool {
    let (dp, dq) = (side(t, p), side(t, q));
    if !straddle(dp, dq) {
        return false;
    }
    if dp == 0.0 && dq == 0.0 {
        return coplanar_segment_meets(p, q, t);
    }
    // The segment reaches the plane; the line pq passes through the triangle iff it turns
    // the same way around all three edges.
    let s =
        [orient3d(p, q, &t[0], &t[1]), orient3d(p, q, &t[1], &t[2]), orient3d(p, q, &t[2], &t[0])];
    s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0)
}

/// Whether two closed, non-degenerate triangles have any point in common.
pub fn triangles_intersect(a: &[Point3<f64>; 3], b: &[Point3<f64>; 3]) -> bool {
    let da = [0, 1, 2].map(|k| side(b, &a[k]));
    let db = [0, 1, 2].map(|k| side(a, &b[k]));
    if one_side(da) || one_side(db) {
        return false;
    }
    (0..3).any(|k| segment_meets_triangle(&a[k], &a[(k + 1) % 3], b))
        || (0..3).any(|k| segment_meets_triangle(&b[k], &b[(k + 1) % 3], a))
}

/// Triangles `i` and `j` of `s` meet beyond the mesh vertices they share (see the module
/// docs for the rules).
fn pair_intersects(s: &TriSurface, i: usize, j: usize) -> bool {
    let (ti, tj) = (s.triangles[i], s.triangles[j]);
    let (a, b) = (s.corners(i), s.corners(j));
    // (corner in i, corner in j) of each shared vertex; no allocation in this hot loop.
    let mut shared = [(0, 0); 3];
    let mut n = 0;
    for (ka, vi) in ti.iter().enumerate() {
        if let Some(kb) = tj.iter().position(|v| v == vi) {
            shared[n] = (ka, kb);
            n += 1;
        }
    }
    match &shared[..n] {
        [] => triangles_intersect(&a, &b),
        &[(ka, kb)] => {
            let (a1, a2) = (a[(ka + 1) % 3], a[(ka + 2) % 3]);
            let (b1, b2) = (b[(kb + 1) % 3], b[(kb + 2) % 3]);
            segment_meets_triangle(&a1, &a2, &b) || segment_meets_triangle(&b1, &b2, &a)
        }
        &[(ka0, _), (ka1, _)] => {
            let (p, q) = (a[ka0], a[ka1]);
            let oa = a[3 - ka0 - ka1];
            let kb = (0..3).find(|&k| !ti.contains(&tj[k])).unwrap_or(0);
            let ob = b[kb];
            if side(&a, &ob) != 0.0 {
                return false;
            }
            let proj = projector(&a);
            let (p, q) = (proj(&p), proj(&q));
            let (sa, sb) = (orient2d(p, q, proj(&oa)), orient2d(p, q, proj(&ob)));
            (sa > 0.0 && sb > 0.0) || (sa < 0.0 && sb < 0.0)
        }
        _ => true,
    }
}

/// Axis-aligned box of triangle `t`.
fn bounds(s: &TriSurface, t: usize) -> (P, P) {
    let [a, b, c] = s.corners(t);
    (a.inf(&b).inf(&c), a.sup(&b).sup(&c))
}

/// A uniform grid of buckets holding the triangles whose boxes overlap each cell, in
/// compressed (offset) form.
struct BucketGrid {
    lo: P,
    cell: f64,
    dims: [usize; 3],
    offsets: Vec<usize>,
    members: Vec<usize>,
}

impl BucketGrid {
    /// A grid over `boxes` (of the triangles `tris`) with about one cell per triangle size
    /// and at most `4·n + 64` cells.
    fn new(tris: &[usize], boxes: &[(P, P)]) -> Self {
        let (lo, hi) = tris.iter().fold(
            (P::from([f64::INFINITY; 3]), P::from([f64::NEG_INFINITY; 3])),
            |(lo, hi), &t| (lo.inf(&boxes[t].0), hi.sup(&boxes[t].1)),
        );
        let ext = (hi - lo).map(|x| x.max(0.0));
        let n = tris.len().max(1);
        let mean = tris.iter().map(|&t| (boxes[t].1 - boxes[t].0).max()).sum::<f64>() / n as f64;
        let max_cells = (4 * n + 64) as f64;
        let mut cell = mean.max(ext.max() * 1e-9).max(f64::MIN_POSITIVE);
        let dims_for = |cell: f64| ext.map(|x| (x / cell).floor().min(1e9) + 1.0);
        for _ in 0..200 {
            let d = dims_for(cell);
            if d.x * d.y * d.z <= max_cells {
                break;
            }
            cell *= 1.25;
        }
        let d = dims_for(cell);
        let dims = [d.x as usize, d.y as usize, d.z as usize];
        let mut grid = BucketGrid { lo, cell, dims, offsets: Vec::new(), members: Vec::new() };
        grid.fill(tris, boxes);
        grid
    }

    /// Cell coordinates of a point, clamped to the grid.
    fn coords(&self, p: &P) -> [usize; 3] {
        [0, 1, 2].map(|k| (((p[k] - self.lo[k]) / self.cell) as usize).min(self.dims[k] - 1))
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Calls `f(cell)` for every cell the box overlaps.
    fn for_cells(&self, b: &(P, P), mut f: impl FnMut(usize)) {
        let (c0, c1) = (self.coords(&b.0), self.coords(&b.1));
        for z in c0[2]..=c1[2] {
            for y in c0[1]..=c1[1] {
                for x in c0[0]..=c1[0] {
                    f(self.index([x, y, z]));
                }
            }
        }
    }

    fn fill(&mut self, tris: &[usize], boxes: &[(P, P)]) {
        let cells = self.dims.iter().product::<usize>();
        let mut offsets = vec![0usize; cells + 1];
        for &t in tris {
            self.for_cells(&boxes[t], |c| offsets[c + 1] += 1);
        }
        for c in 0..cells {
            offsets[c + 1] += offsets[c];
        }
        let mut next = offsets.clone();
        let mut members = vec![0usize; offsets[cells]];
        for &t in tris {
            self.for_cells(&boxes[t], |c| {
                members[next[c]] = t;
                next[c] += 1;
            });
        }
        self.offsets = offsets;
        self.members = members;
    }

    fn cell_members(&self, c: usize) -> &[usize] {
        &self.members[self.offsets[c]..self.offsets[c + 1]]
    }
}

fn boxes_overlap(a: &(P, P), b: &(P, P)) -> bool {
    (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
}

impl TriSurface {
    /// All pairs of triangles that cross or overlap beyond the vertices or edge they share,
    /// sorted; empty for a surface that does not intersect itself. See the
    /// [module docs](crate::self_intersection) for what counts and the bucket grid that keeps
    /// this near-linear in the number of triangles.
    pub fn self_intersections(&self) -> Vec<SelfIntersection> {
        let nv = self.vertices.len();
        let tol = self.zero_area_tolerance();
        let usable = |t: usize| {
            let tri = self.triangles[t];
            tri.iter().all(|&v| v < nv && self.vertices[v].iter().all(|x| x.is_finite()))
                && !self.is_degenerate(t, tol)
        };
        let tris: Vec<usize> = (0..self.triangles.len()).filter(|&t| usable(t)).collect();
        if tris.len() < 2 {
            return Vec::new();
        }
        let mut boxes = vec![(P::origin(), P::origin()); self.triangles.len()];
        for &t in &tris {
            boxes[t] = bounds(self, t);
        }
        let grid = BucketGrid::new(&tris, &boxes);
        let mut found = Vec::new();
        for c in 0..grid.offsets.len() - 1 {
            let m = grid.cell_members(c);
            for (k, &i) in m.iter().enumerate() {
                for &j in &m[k + 1..] {
                    let (bi, bj) = (&boxes[i], &boxes[j]);
                    // Test each pair once: in the cell of the low corner of the boxes' overlap.
                    if !boxes_overlap(bi, bj) || grid.index(grid.coords(&bi.0.sup(&bj.0))) != c {
                        continue;
                    }
                    if pair_intersects(self, i, j) {
                        found.push(SelfIntersection { first: i.min(j), second: i.max(j) });
                    }
                }
            }
        }
        found.sort_unstable();
        found
    }
}

#[cfg(test)]
mod tests;
