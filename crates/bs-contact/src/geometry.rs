//! Geometric predicates: closest points on triangles and segments, circumcentres.
//!
//! The point–triangle query classifies the query point into one of the seven Voronoi
//! regions of a triangle (three vertex regions, three edge regions, the face region) using
//! only dot products of the query with the two edge vectors at each corner, in the manner
//! described in Ericson, *Real-Time Collision Detection*, §5.1.5. The formulation here is our
//! own: each corner test asks whether the query lies behind both edges leaving the corner,
//! each edge test uses the sign of a 2×2 determinant (a scaled barycentric coordinate).

use nalgebra::{Point3, Vector3};

/// One of the seven Voronoi regions of a triangle `[a, b, c]` (local corner indices 0, 1, 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TriRegion {
    /// The closest point is corner `i`.
    Vertex(u8),
    /// The closest point is inside edge `i` → `(i + 1) % 3`.
    Edge(u8),
    /// The closest point is inside the triangle.
    Face,
}

/// Closest point of the triangle `[a, b, c]` to `p`, and the Voronoi region `p` lies in.
///
/// Exact up to rounding for any non-degenerate triangle; for a degenerate one (zero area)
/// it still returns a point of the triangle.
pub fn closest_point_triangle(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> (Point3<f64>, TriRegion) {
    let e_ab = b - a;
    let e_ac = c - a;

    // Corner a: behind both edges leaving a.
    let ap = p - a;
    let ab_ap = e_ab.dot(&ap);
    let ac_ap = e_ac.dot(&ap);
    if ab_ap <= 0.0 && ac_ap <= 0.0 {
        return (*a, TriRegion::Vertex(0));
    }

    // Corner b: behind edge b→a (ab·bp ≥ 0) and behind edge b→c ((c−b)·bp ≤ 0).
    let bp = p - b;
    let ab_bp = e_ab.dot(&bp);
    let ac_bp = e_ac.dot(&bp);
    if ab_bp >= 0.0 && ac_bp <= ab_bp {
        return (*b, TriRegion::Vertex(1));
    }

    // Edge ab: the scaled barycentric weight of c is ≤ 0 and p projects between a and b.
    let w_c = ab_ap * ac_bp - ab_bp * ac_ap;
    if w_c <= 0.0 && ab_ap >= 0.0 && ab_bp <= 0.0 {
        let t = ab_ap / (ab_ap - ab_bp);
        return (a + e_ab * t, TriRegion::Edge(0));
    }

    // Corner c.
    let cp = p - c;
    let ab_cp = e_ab.dot(&cp);
    let ac_cp = e_ac.dot(&cp);
    if ac_cp >= 0.0 && ab_cp <= ac_cp {
        return (*c, TriRegion::Vertex(2));
    }

    // Edge ca: the scaled weight of b is ≤ 0 and p projects between c and a.
    let w_b = ab_cp * ac_ap - ab_ap * ac_cp;
    if w_b <= 0.0 && ac_ap >= 0.0 && ac_cp <= 0.0 {
        let t = ac_ap / (ac_ap - ac_cp);
        return (a + e_ac * t, TriRegion::Edge(2));
    }

    // Edge bc: the scaled weight of a is ≤ 0 and p projects between b and c.
    let w_a = ab_bp * ac_cp - ab_cp * ac_bp;
    let along_b = ac_bp - ab_bp;
    let along_c = ab_cp - ac_cp;
    if w_a <= 0.0 && along_b >= 0.0 && along_c >= 0.0 {
        let t = along_b / (along_b + along_c);
        return (b + (c - b) * t, TriRegion::Edge(1));
    }

    // Face: barycentric coordinates from the scaled weights.
    let sum = w_a + w_b + w_c;
    let v = w_b / sum;
    let w = w_c / sum;
    (a + e_ab * v + e_ac * w, TriRegion::Face)
}

/// Closest point of segment `[a, b]` to `p` and its parameter `t ∈ [0, 1]`.
pub fn closest_point_segment(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
) -> (Point3<f64>, f64) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    if len2 == 0.0 {
        return (*a, 0.0);
    }
    let t = ((p - a).dot(&ab) / len2).clamp(0.0, 1.0);
    (a + ab * t, t)
}

/// Circumcentre of triangle `[a, b, c]` (in its plane), or `None` when the points are
/// collinear (the circumcircle is at infinity).
pub fn circumcentre(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> Option<Point3<f64>> {
    let u = b - a;
    let v = c - a;
    let w = u.cross(&v);
    let w2 = w.norm_squared();
    let scale = u.norm_squared().max(v.norm_squared());
    if w2 <= 1e-24 * scale * scale || !w2.is_finite() {
        return None;
    }
    // Standard closed form: O − a = (|u|² v × w + |v|² w × u) / (2 |w|²).
    let o = (v.cross(&w) * u.norm_squared() + w.cross(&u) * v.norm_squared()) / (2.0 * w2);
    Some(a + o)
}

/// Unit normal of triangle `[a, b, c]` (right-hand rule) and its area.
pub fn triangle_normal(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> (Vector3<f64>, f64) {
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    if len == 0.0 { (Vector3::zeros(), 0.0) } else { (n / len, 0.5 * len) }
}

/// Interior angle of triangle `[a, b, c]` at corner `a`, in radians.
pub fn corner_angle(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> f64 {
    let u = b - a;
    let v = c - a;
    u.cross(&v).norm().atan2(u.dot(&v))
}

/// Whether the projection of `p` on the plane of the triangle lies inside the closed
/// triangle, and the projected point. `n` is the triangle's unit normal.
#[inline]
pub fn project_inside_triangle(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
    n: &Vector3<f64>,
) -> Option<Point3<f64>> {
    let r = p - n * (p - a).dot(n);
    // Signed sub-triangle areas (times 2) around the normal: all ≥ 0 ⇔ r inside.
    let ea = (b - a).cross(&(r - a)).dot(n);
    let eb = (c - b).cross(&(r - b)).dot(n);
    let ec = (a - c).cross(&(r - c)).dot(n);
    if ea >= 0.0 && eb >= 0.0 && ec >= 0.0 { Some(r) } else { None }
}

/// Projection of `p` on the line through `a` and `b` when it falls inside the closed
/// segment, else `None`.
#[inline]
pub fn project_inside_segment(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
) -> Option<Point3<f64>> {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = (p - a).dot(&ab);
    if t >= 0.0 && t <= len2 && len2 > 0.0 { Some(a + ab * (t / len2)) } else { None }
}
