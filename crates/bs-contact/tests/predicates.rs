//! Property tests of the geometric predicates: point–triangle closest point in all seven
//! Voronoi regions, normals, the §3.2 list tests, bucket sizes, the exact nearest-node search.
#![allow(clippy::needless_range_loop)]

mod common;

use bs_contact::geometry::{TriRegion, closest_point_triangle, corner_angle};
use bs_contact::grid::BucketGrid;
use bs_contact::paper::{
    edge_needs_check, edge_needs_check_literal, face_needs_check, face_needs_check_literal,
};
use bs_contact::shapes::{self, Rng};
use bs_contact::{MasterSurface, NodeNormalRule, PaperContact, PaperParams};
use bs_mesh::{Point3, Vector3};
use common::cube;
use proptest::prelude::*;

fn pt() -> impl Strategy<Value = Point3<f64>> {
    (-2.0..2.0f64, -2.0..2.0f64, -2.0..2.0f64).prop_map(|(x, y, z)| Point3::new(x, y, z))
}

/// Independent reference: the nearest of the three vertices, the three edge interiors
/// (clamped projection) and the plane projection when its barycentric coordinates (from
/// solving the 2×2 normal equations) are all positive. Returns the point and the region of
/// the winner.
fn reference(p: &Point3<f64>, t: [Point3<f64>; 3]) -> (Point3<f64>, TriRegion) {
    let mut best = (f64::INFINITY, t[0], TriRegion::Vertex(0));
    let mut offer = |q: Point3<f64>, r: TriRegion| {
        let d = (q - p).norm_squared();
        if d < best.0 {
            best = (d, q, r);
        }
    };
    for k in 0..3 {
        offer(t[k], TriRegion::Vertex(k as u8));
    }
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let s = (p - a).dot(&(b - a)) / (b - a).norm_squared();
        if s > 0.0 && s < 1.0 {
            offer(a + (b - a) * s, TriRegion::Edge(k as u8));
        }
    }
    let (u, v, w) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (uu, uv, vv, wu, wv) = (u.dot(&u), u.dot(&v), v.dot(&v), w.dot(&u), w.dot(&v));
    let det = uu * vv - uv * uv;
    let (l1, l2) = ((wu * vv - wv * uv) / det, (wv * uu - wu * uv) / det);
    if l1 > 0.0 && l2 > 0.0 && l1 + l2 < 1.0 {
        offer(t[0] + u * l1 + v * l2, TriRegion::Face);
    }
    (best.1, best.2)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Closest point equals the independent reference (distance to 1e-12 of the triangle
    /// size: both are exact formulas, differences are rounding), and the region matches
    /// whenever the query is not within 1e-9 of a region boundary.
    #[test]
    fn closest_point_triangle_matches_reference(p in pt(), a in pt(), b in pt(), c in pt()) {
        let area = (b - a).cross(&(c - a)).norm();
        prop_assume!(area > 1e-3);
        let (q, region) = closest_point_triangle(&p, &a, &b, &c);
        let (r, rregion) = reference(&p, [a, b, c]);
        let scale = 1.0 + (p - a).norm();
        prop_assert!(((q - p).norm() - (r - p).norm()).abs() <= 1e-12 * scale * 4.0);
        prop_assert!((q - r).norm() <= 1e-6 * scale);
        // Region agreement away from boundaries: perturb and check stability.
        let stable = [Vector3::x(), Vector3::y(), Vector3::z()].iter().all(|e| {
            let (_, r1) = reference(&(p + e * 1e-7), [a, b, c]);
            let (_, r2) = reference(&(p - e * 1e-7), [a, b, c]);
            r1 == rregion && r2 == rregion
        });
        if stable {
            prop_assert_eq!(region, rregion);
        }
    }

    /// §3.2 edge reading: `[CM] < [AM]` with M the midpoint of AB holds iff some point of AB
    /// is closer to C than to both A and B (dense sampling of AB).
    #[test]
    fn edge_crossing_reading_uses_the_midpoint(a in pt(), b in pt(), c in pt()) {
        prop_assume!((b - a).norm() > 1e-2);
        let m = nalgebra::center(&a, &b);
        let crossing = (c - m).norm() < (a - m).norm();
        let sampled = (0..=2000).any(|i| {
            let x = a + (b - a) * (i as f64 / 2000.0);
            let xc = (x - c).norm();
            xc < (x - a).norm() && xc < (x - b).norm()
        });
        // Sampling can miss a crossing narrower than 1/2000 of AB: only check the margin.
        let margin = ((c - m).norm() - (a - m).norm()).abs() / (b - a).norm();
        if margin > 1e-3 {
            prop_assert_eq!(crossing, sampled);
        }
    }

    /// The edge test as implemented never rejects an edge that a point within d of AB and
    /// closer to C than to A and B demonstrates (random witnesses), and accepts everything
    /// the printed test accepts.
    #[test]
    fn edge_test_is_sound(a in pt(), b in pt(), c in pt(), d in 0.0..1.0f64, seed in any::<u64>()) {
        prop_assume!((b - a).norm() > 1e-2 && (c - a).norm() > 1e-2 && (c - b).norm() > 1e-2);
        let ours = edge_needs_check(&c, &a, &b, d);
        if edge_needs_check_literal(&c, &a, &b, d) {
            prop_assert!(ours);
        }
        let mut rng = Rng::new(seed);
        for _ in 0..200 {
            let x = a + (b - a) * rng.uniform();
            let y = x + rng.direction() * (d * rng.uniform());
            let yc = (y - c).norm();
            if yc < (y - a).norm() && yc < (y - b).norm() {
                prop_assert!(ours, "witness {:?} within d of AB is closer to C", y);
            }
        }
    }

    /// Face test discard: when [CR] > 2ρ no point of the triangle is closer to C than to
    /// its vertices (random points of the face); and a face some of whose sample points S
    /// lie in R is accepted.
    #[test]
    fn face_discard_is_sound(a in pt(), b in pt(), t3 in pt(), c in pt(), seed in any::<u64>()) {
        let area = (b - a).cross(&(t3 - a)).norm();
        prop_assume!(area > 1e-2);
        let n = (b - a).cross(&(t3 - a)).normalize();
        let r = bs_contact::geometry::circumcentre(&a, &b, &t3).unwrap();
        let rho = (a - r).norm();
        let accepted0 = face_needs_check(&c, [&a, &b, &t3], &n, 0.0);
        let mut rng = Rng::new(seed);
        let mut witness = false;
        for _ in 0..300 {
            let (mut u, mut v) = (rng.uniform(), rng.uniform());
            if u + v > 1.0 { u = 1.0 - u; v = 1.0 - v; }
            let x = a + (b - a) * u + (t3 - a) * v;
            let xc = (x - c).norm();
            if xc < (x - a).norm() && xc < (x - b).norm() && xc < (x - t3).norm() {
                witness = true;
            }
        }
        if (c - r).norm() > 2.0 * rho {
            prop_assert!(!witness);
            prop_assert!(!accepted0);
        }
        // Edge midpoints and vertices are the S points at d = 0: if one is in R, accepted.
        let mids = [nalgebra::center(&a, &b), nalgebra::center(&b, &t3), nalgebra::center(&t3, &a)];
        let in_r = |s: &Point3<f64>| {
            let sc = (s - c).norm();
            sc < (s - a).norm() && sc < (s - b).norm() && sc < (s - t3).norm()
        };
        if mids.iter().any(in_r) && (c - r).norm() <= 2.0 * rho {
            prop_assert!(accepted0);
        }
    }

    /// The face test as implemented accepts every face for which a random witness within d
    /// of the face interior (either side) is closer to C than to the face's vertices, and
    /// everything the printed test accepts.
    #[test]
    fn face_test_is_sound(a in pt(), b in pt(), t3 in pt(), c in pt(), d in 0.0..1.0f64, seed in any::<u64>()) {
        let area = (b - a).cross(&(t3 - a)).norm();
        prop_assume!(area > 1e-2);
        let n = (b - a).cross(&(t3 - a)).normalize();
        let ours = face_needs_check(&c, [&a, &b, &t3], &n, d);
        if face_needs_check_literal(&c, [&a, &b, &t3], &n, d) {
            prop_assert!(ours);
        }
        let mut rng = Rng::new(seed);
        for _ in 0..300 {
            let (mut u, mut v) = (rng.uniform(), rng.uniform());
            if u + v > 1.0 { u = 1.0 - u; v = 1.0 - v; }
            let y = a + (b - a) * u + (t3 - a) * v + n * rng.range(-d, d);
            let yc = (y - c).norm();
            if yc < (y - a).norm() && yc < (y - b).norm() && yc < (y - t3).norm() {
                prop_assert!(ours, "witness {:?} within d of the face is closer to C", y);
            }
        }
    }

    /// The bucket search returns the exact nearest point (brute force), for queries inside
    /// and far outside the grid, and a valid lower bound on every other point.
    #[test]
    fn bucket_nearest_is_exact(seed in any::<u64>(), hx in 0.05..0.5f64, hy in 0.05..0.5f64, hz in 0.05..0.5f64) {
        let mut rng = Rng::new(seed);
        let items: Vec<(u32, Point3<f64>)> = (0..60)
            .map(|i| (i, Point3::new(rng.uniform(), rng.uniform() * 2.0, rng.uniform() * 0.5)))
            .collect();
        let grid = BucketGrid::new(&items, Vector3::new(hx, hy, hz));
        for _ in 0..30 {
            let q = Point3::new(rng.range(-2.0, 3.0), rng.range(-2.0, 4.0), rng.range(-2.0, 2.5));
            let n = grid.nearest(&q, true).unwrap();
            let mut d: Vec<(f64, u32)> = items.iter().map(|(i, p)| ((p - q).norm_squared(), *i)).collect();
            d.sort_by(|x, y| x.partial_cmp(y).unwrap());
            prop_assert_eq!(n.d2, d[0].0);
            prop_assert!(n.other_lb <= d[1].0.sqrt() + 1e-12);
        }
    }
}

/// Every one of the seven regions is produced, each agreeing with the reference.
#[test]
fn all_seven_regions_are_classified() {
    let t = [Point3::new(0.0, 0.0, 0.0), Point3::new(2.0, 0.0, 0.0), Point3::new(0.5, 1.5, 0.0)];
    let mut seen = std::collections::HashSet::new();
    for i in -10..=30 {
        for j in -10..=30 {
            for z in [-0.7, 0.0, 0.4] {
                let p = Point3::new(i as f64 * 0.1 - 0.5, j as f64 * 0.1 - 0.5, z);
                let (q, region) = closest_point_triangle(&p, &t[0], &t[1], &t[2]);
                let (r, rr) = reference(&p, t);
                assert!((q - r).norm() < 1e-12, "{p:?}");
                if (q - r).norm() < 1e-12 && region == rr {
                    seen.insert(region);
                }
            }
        }
    }
    assert_eq!(seen.len(), 7, "{seen:?}");
}

/// Node normals: at a cube corner the angle-weighted normal is along (±1, ±1, ±1) whatever
/// the triangulation; the plain sum is not (it counts the split face twice). Edge normals
/// are the sum of the two face normals, perpendicular to the edge.
#[test]
fn node_and_edge_normals() {
    let m = MasterSurface::new(&cube()).unwrap();
    for (v, n) in m.node_normals().iter().enumerate() {
        let corner = m.vertices()[v].coords.map(|x| if x > 0.5 { 1.0 } else { -1.0 });
        let cos = n.normalize().dot(&corner.normalize());
        assert!((cos - 1.0).abs() < 1e-12, "vertex {v}: {n:?}");
    }
    let plain = MasterSurface::with_rule(&cube(), NodeNormalRule::PlainSum).unwrap();
    let skewed = plain.node_normals().iter().enumerate().any(|(v, n)| {
        let corner = plain.vertices()[v].coords.map(|x| if x > 0.5 { 1.0 } else { -1.0 });
        (n.normalize().dot(&corner.normalize()) - 1.0).abs() > 1e-3
    });
    assert!(skewed, "the plain sum is triangulation dependent at cube corners");
    for (e, ab) in m.edges().iter().enumerate() {
        let [f1, f2] = m.edge_faces()[e];
        let sum = m.face_normals()[f1 as usize] + m.face_normals()[f2 as usize];
        assert_eq!(m.edge_normals()[e], sum);
        let dir = m.vertices()[ab[1] as usize] - m.vertices()[ab[0] as usize];
        assert!(sum.dot(&dir).abs() < 1e-12);
    }
    // Angles at each node of a closed convex surface sum to less than 2π, bisectors are unit
    // and inside their corner.
    let s = shapes::random_convex(40, 1);
    let m = MasterSurface::new(&s).unwrap();
    for (f, t) in m.triangles().iter().enumerate() {
        for k in 0..3 {
            let (c, u, w) = (
                m.vertices()[t[k] as usize],
                m.vertices()[t[(k + 1) % 3] as usize],
                m.vertices()[t[(k + 2) % 3] as usize],
            );
            let b = m.bisectors()[f][k];
            assert!((b.norm() - 1.0).abs() < 1e-12);
            let half = corner_angle(&c, &u, &w) / 2.0;
            assert!(((u - c).normalize().dot(&b) - half.cos()).abs() < 1e-9);
            assert!(((w - c).normalize().dot(&b) - half.cos()).abs() < 1e-9);
        }
    }
}

/// Bucket size of the node grid = half the largest edge projection on each axis (computed
/// here from the triangles), and r = longest edge at each node.
#[test]
fn bucket_sizes_and_node_radii() {
    let s = shapes::ellipsoid(300, Vector3::new(3.0, 2.0, 1.0));
    let paper = PaperContact::new(&s, PaperParams::default()).unwrap();
    let mut proj = [0.0f64; 3];
    let mut radius = vec![0.0f64; s.vertices.len()];
    for t in &s.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let e = s.vertices[b] - s.vertices[a];
            for ax in 0..3 {
                proj[ax] = proj[ax].max(e[ax].abs());
            }
            radius[a] = radius[a].max(e.norm());
            radius[b] = radius[b].max(e.norm());
        }
    }
    for ax in 0..3 {
        assert_eq!(paper.grid().h[ax], 0.5 * proj[ax]);
    }
    assert_eq!(paper.master().node_radius(), radius);
    // Ellipsoid 3:2:1 → anisotropic buckets.
    assert!(paper.grid().h[0] > paper.grid().h[2]);
}
