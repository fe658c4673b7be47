use std::collections::HashMap;

use nalgebra::Vector3;
use proptest::prelude::*;

use super::*;
use crate::SurfaceError;

/// An outward icosphere: the icosahedron subdivided `level` times, projected to the sphere.
pub(crate) fn icosphere(level: usize, center: Vector3<f64>, radius: f64) -> TriSurface {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<Vector3<f64>> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vector3::from(*p).normalize())
    .collect();
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut m = |a: usize, b: usize, v: &mut Vec<Vector3<f64>>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a] + v[b]) / 2.0).normalize());
                v.len() - 1
            })
        };
        let mut next = Vec::with_capacity(4 * f.len());
        for &[a, b, c] in &f {
            let (ab, bc, ca) = (m(a, b, &mut v), m(b, c, &mut v), m(c, a, &mut v));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    let vertices = v.iter().map(|p| Point3::from(center + radius * p)).collect();
    TriSurface::new(vertices, f)
}

/// Two surfaces as one (the second's indices shifted).
fn union(a: &TriSurface, b: &TriSurface) -> TriSurface {
    let n = a.vertices.len();
    let mut s = a.clone();
    s.vertices.extend_from_slice(&b.vertices);
    s.triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + n)));
    s
}

/// Every pair, no grid: the reference for the bucket grid.
fn brute_force(s: &TriSurface) -> Vec<SelfIntersection> {
    let tol = s.zero_area_tolerance();
    let usable = |t: usize| !s.is_degenerate(t, tol);
    let mut found = Vec::new();
    for i in 0..s.triangles.len() {
        for j in i + 1..s.triangles.len() {
            if usable(i) && usable(j) && pair_intersects(s, i, j) {
                found.push(SelfIntersection { first: i, second: j });
            }
        }
    }
    found
}

/// Möller's interval test for two triangles in general position (no vertex on the other's
/// plane): an independent reference for [`triangles_intersect`].
fn moller(a: &[P; 3], b: &[P; 3]) -> bool {
    let signed = |t: &[P; 3], p: &P| {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        n.dot(&(p - t[0]))
    };
    let da = a.map(|p| signed(b, &p));
    let db = b.map(|p| signed(a, &p));
    if one_side(da) || one_side(db) {
        return false;
    }
    let na = (a[1] - a[0]).cross(&(a[2] - a[0]));
    let nb = (b[1] - b[0]).cross(&(b[2] - b[0]));
    let dir = na.cross(&nb);
    // Where the triangle's edges cross the other plane, as positions along the line.
    let interval = |t: &[P; 3], d: [f64; 3]| {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for k in 0..3 {
            let (i, j) = (k, (k + 1) % 3);
            if (d[i] > 0.0) != (d[j] > 0.0) {
                let p = t[i] + (t[j] - t[i]) * (d[i] / (d[i] - d[j]));
                let x = dir.dot(&p.coords);
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
        (lo, hi)
    };
    let (a0, a1) = interval(a, da);
    let (b0, b1) = interval(b, db);
    a0 <= b1 && b0 <= a1
}

fn tri(p: [[f64; 3]; 3]) -> [P; 3] {
    p.map(P::from)
}

#[test]
fn clean_sphere_has_no_self_intersection() {
    let s = icosphere(3, Vector3::zeros(), 10.0);
    assert_eq!(s.triangles.len(), 1280);
    assert!(s.self_intersections().is_empty());
    assert!(s.require_closed_outward().is_ok());
    assert!(s.check().unwrap().self_intersections.is_empty());
}

#[test]
fn two_overlapping_spheres_are_detected_and_named() {
    let a = icosphere(2, Vector3::zeros(), 10.0);
    let b = icosphere(2, Vector3::new(6.0, 0.0, 0.0), 10.0);
    let s = union(&a, &b);
    // Each shell on its own is a valid skull, and so is their union topologically.
    let c = s.check().unwrap();
    assert!(c.is_closed_outward(), "{c:?}");
    let found = s.self_intersections();
    assert_eq!(found, brute_force(&s));
    assert!(!found.is_empty());
    let n = a.triangles.len();
    assert!(found.iter().all(|p| p.first < n && p.second >= n), "only cross-shell pairs");
    assert_eq!(c.self_intersections, found);
    let e = s.require_closed_outward().unwrap_err();
    assert_eq!(e, SurfaceError::SelfIntersecting { count: found.len(), example: found[0] });
    let msg = e.to_string();
    let names = format!("triangles {} and {}", found[0].first, found[0].second);
    assert!(msg.contains(&names) && msg.contains("remesh"), "{msg}");
    // Far apart, the same two shells do not touch.
    let far = union(&a, &icosphere(2, Vector3::new(25.0, 0.0, 0.0), 10.0));
    assert!(far.self_intersections().is_empty());
}

#[test]
fn a_vertex_pushed_through_the_opposite_side_is_detected() {
    // The bottom apex pulled up and sideways through the top faces: one closed, manifold,
    // consistently oriented shell that crosses itself.
    let mut s = crate::surface::tests::octahedron();
    s.vertices[5] = Point3::new(0.9, 0.9, 0.5);
    let c = s.check().unwrap();
    assert!(c.is_closed_manifold() && c.misoriented_edges == 0, "{c:?}");
    let found = s.self_intersections();
    assert_eq!(found, brute_force(&s));
    assert!(!found.is_empty());
    // Only top faces (0–3, around apex 4) cross bottom faces (4–7, around apex 5).
    assert!(found.iter().all(|p| p.first < 4 && p.second >= 4), "{found:?}");
}

#[test]
fn neighbours_touching_along_their_edge_or_vertex_do_not_count() {
    // A shared edge, non-coplanar and coplanar unfolded: no intersection.
    let v = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
    let mut s = TriSurface::new(
        vec![v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, -1.0, 0.3)],
        vec![[0, 1, 2], [1, 0, 3]],
    );
    assert!(s.self_intersections().is_empty());
    s.vertices[3] = v(0.0, -1.0, 0.0);
    assert!(s.self_intersections().is_empty());
    // Folded onto each other (coplanar, same side): an overlap.
    s.vertices[3] = v(0.5, 0.7, 0.0);
    assert_eq!(s.self_intersections(), [SelfIntersection { first: 0, second: 1 }]);
    // A shared vertex only: a fan neighbour is fine, one passing through is not.
    let mut s = TriSurface::new(
        vec![
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, 1.0, 0.0),
            v(-1.0, 0.0, 0.0),
            v(0.0, -1.0, 0.0),
        ],
        vec![[0, 1, 2], [0, 3, 4]],
    );
    assert!(s.self_intersections().is_empty());
    s.vertices[3] = v(0.5, 0.2, -1.0);
    s.vertices[4] = v(0.2, 0.5, 1.0);
    assert_eq!(s.self_intersections().len(), 1);
}

#[test]
fn triangle_pairs_in_special_positions() {
    let base = tri([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]]);
    // Piercing, touching at a point, apart, coplanar overlapping, coplanar disjoint.
    let cases = [
        ([[1.0, 1.0, -1.0], [1.0, 1.0, 1.0], [2.0, 3.0, 1.0]], true),
        ([[1.0, 1.0, 0.0], [1.0, 1.0, 1.0], [2.0, 1.0, 1.0]], true),
        ([[1.0, 1.0, 0.5], [1.0, 2.0, 1.0], [2.0, 1.0, 1.0]], false),
        ([[1.0, 1.0, 0.0], [5.0, 1.0, 0.0], [1.0, 5.0, 0.0]], true),
        ([[3.0, 3.0, 0.0], [5.0, 3.0, 0.0], [3.0, 5.0, 0.0]], false),
        // One inside the other, coplanar.
        ([[0.5, 0.5, 0.0], [1.0, 0.5, 0.0], [0.5, 1.0, 0.0]], true),
    ];
    for (k, (b, expect)) in cases.iter().enumerate() {
        let b = tri(*b);
        assert_eq!(triangles_intersect(&base, &b), *expect, "case {k}");
        assert_eq!(triangles_intersect(&b, &base), *expect, "case {k} swapped");
    }
}

/// A random triangle soup over a small pool of vertices, so that shared vertices and edges,
/// duplicates, coplanar and touching pairs all occur; integer coordinates make the
/// predicates exact, so the touching cases are real.
fn soup(integer: bool) -> impl Strategy<Value = TriSurface> {
    let coord =
        if integer { (0i32..4).prop_map(f64::from).boxed() } else { (-2.0..2.0f64).boxed() };
    (4usize..12)
        .prop_flat_map(move |nv| {
            let pts = prop::collection::vec([coord.clone(), coord.clone(), coord.clone()], nv);
            let tris = prop::collection::vec([0..nv, 0..nv, 0..nv], 2..24);
            (pts, tris)
        })
        .prop_map(|(pts, tris)| TriSurface::new(pts.into_iter().map(P::from).collect(), tris))
}

/// The grid finds the brute-force pairs; and, independently of the predicate's details, every
/// pair has overlapping boxes and the test is symmetric.
fn check_against_brute_force(s: &TriSurface) -> Result<(), TestCaseError> {
    let found = brute_force(s);
    prop_assert_eq!(s.self_intersections(), found.clone());
    for p in &found {
        prop_assert!(boxes_overlap(&bounds(s, p.first), &bounds(s, p.second)), "{:?}", p);
        prop_assert!(pair_intersects(s, p.second, p.first), "{:?} not symmetric", p);
    }
    Ok(())
}

proptest! {
    #[test]
    fn grid_finds_exactly_the_brute_force_pairs(s in soup(true)) {
        check_against_brute_force(&s)?;
    }

    #[test]
    fn grid_finds_exactly_the_brute_force_pairs_float(s in soup(false)) {
        check_against_brute_force(&s)?;
    }

    #[test]
    fn predicate_agrees_with_moller_in_general_position(
        a in prop::array::uniform3(prop::array::uniform3(-1.0..1.0f64)),
        b in prop::array::uniform3(prop::array::uniform3(-1.0..1.0f64)),
    ) {
        let (a, b) = (tri(a), tri(b));
        prop_assert_eq!(triangles_intersect(&a, &b), moller(&a, &b));
    }
}

#[test]
fn a_fine_sphere_is_fast_and_clean() {
    // 5 120 triangles by default (BS_ICOSPHERE_LEVEL=6 for 81 920: about 6 s in this
    // unoptimised test build, where nalgebra is not inlined).
    let level = std::env::var("BS_ICOSPHERE_LEVEL").ok().and_then(|l| l.parse().ok()).unwrap_or(4);
    let s = icosphere(level, Vector3::new(1.0, 2.0, 3.0), 80.0);
    let start = std::time::Instant::now();
    assert!(s.self_intersections().is_empty());
    eprintln!("{} triangles: {:?}", s.triangles.len(), start.elapsed());
}
