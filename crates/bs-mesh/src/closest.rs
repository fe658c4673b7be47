//! The closest point of a triangle to a point, and the Voronoi region it lies in: the one
//! routine every point–triangle query uses (contact, locating points outside a mesh,
//! surface loads).
//!
//! The query classifies the point into one of the seven Voronoi regions of a triangle
//! (three vertex regions, three edge regions, the face region) using only dot products of
//! the query with the two edge vectors at each corner, in the manner described in Ericson,
//! *Real-Time Collision Detection*, §5.1.5. The formulation here is our own: each corner test
//! asks whether the query lies behind both edges leaving the corner, each edge test uses the
//! sign of a 2×2 determinant (a scaled barycentric coordinate).

use nalgebra::Point3;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// Against brute force: the distance to the returned point is never more than the
    /// smallest distance to 20 301 points of a barycentric lattice on the triangle (so no
    /// lattice point is closer), and it lies within the lattice's spacing of it; the region
    /// matches where the point is (a vertex, an edge or inside).
    #[test]
    fn the_closest_point_is_no_farther_than_any_point_of_the_triangle() {
        let mut rng = SplitMix64::new(29);
        let mut r =
            || Point3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        for _ in 0..200 {
            let (a, b, c, p) = (r(), r(), r(), r() * 2.0);
            let (q, region) = closest_point_triangle(&p, &a, &b, &c);
            let n = 200;
            let mut best = f64::INFINITY;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let x = a + (b - a) * u + (c - a) * v;
                    best = best.min((p - x).norm());
                }
            }
            let d = (p - q).norm();
            let spacing =
                [(b - a).norm(), (c - a).norm(), (c - b).norm()].into_iter().fold(0.0, f64::max)
                    / n as f64;
            assert!(d <= best + 1e-12 && d >= best - spacing, "{d} vs {best}");
            let corners = [a, b, c];
            match region {
                TriRegion::Vertex(k) => assert_eq!(q, corners[k as usize]),
                TriRegion::Edge(k) => {
                    let (s, e) = (corners[k as usize], corners[(k as usize + 1) % 3]);
                    let off = (q - s).cross(&(e - s)).norm() / (e - s).norm();
                    assert!(off < 1e-12, "edge {k}: {off}");
                }
                TriRegion::Face => {
                    let normal = (b - a).cross(&(c - a));
                    assert!((q - a).dot(&normal).abs() < 1e-12 * normal.norm());
                }
            }
        }
    }
}
