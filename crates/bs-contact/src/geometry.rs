//! Geometric predicates: closest points on triangles and segments, circumcentres.
//!
//! The point–triangle query is bs-mesh's ([`bs_mesh::closest`]), re-exported here.

use nalgebra::{Point3, Vector3};

pub use bs_mesh::closest::{TriRegion, closest_point_triangle};

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
