//! Closed test surfaces for tests and benchmarks: spheres and ellipsoids from the convex
//! hull of a Fibonacci point set, radially perturbed (bumpy, non-convex) spheres, random
//! convex polyhedra, midpoint refinement. Deterministic (seeded) so results reproduce.

use bs_mesh::TriSurface;
use nalgebra::{Point3, Vector3};
use parry3d_f64::math::Vector as PVec;

/// The workspace's one seeded generator (SplitMix64), under the name these tests use.
pub use bs_mesh::rng::SplitMix64 as Rng;

/// Convex hull of a point set as an outward-oriented closed surface.
pub fn convex_hull(points: &[Point3<f64>]) -> TriSurface {
    let pts: Vec<PVec> = points.iter().map(|p| PVec::new(p.x, p.y, p.z)).collect();
    let (v, t) = parry3d_f64::transformation::convex_hull(&pts);
    let mut s = TriSurface {
        vertices: v.iter().map(|p| Point3::new(p.x, p.y, p.z)).collect(),
        triangles: t.iter().map(|t| [t[0] as usize, t[1] as usize, t[2] as usize]).collect(),
    };
    orient_outward(&mut s);
    s
}

/// Flips every triangle if the signed enclosed volume is negative.
pub fn orient_outward(s: &mut TriSurface) {
    let vol: f64 = s
        .triangles
        .iter()
        .map(|t| {
            s.vertices[t[0]].coords.dot(&s.vertices[t[1]].coords.cross(&s.vertices[t[2]].coords))
        })
        .sum();
    if vol < 0.0 {
        for t in &mut s.triangles {
            t.swap(1, 2);
        }
    }
}

/// `n` points of a Fibonacci lattice on the unit sphere.
pub fn fibonacci_points(n: usize) -> Vec<Point3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            Point3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Unit sphere with `n` near-uniform vertices (2n − 4 triangles).
pub fn sphere(n: usize) -> TriSurface {
    convex_hull(&fibonacci_points(n))
}

/// Ellipsoid with semi-axes `radii` and `n` vertices (2n − 4 triangles).
pub fn ellipsoid(n: usize, radii: Vector3<f64>) -> TriSurface {
    let mut s = sphere(n);
    for v in &mut s.vertices {
        *v = Point3::from(v.coords.component_mul(&radii));
    }
    s
}

/// A non-convex closed surface: the unit sphere with `n` vertices pushed radially to
/// `r(u) = 1 + Σ a_k exp(−|u − c_k|² / w_k²)` with `bumps` random bumps, half dents
/// (a_k < 0) and half ridges (a_k > 0), amplitude up to `amplitude`.
pub fn bumpy_sphere(n: usize, bumps: usize, amplitude: f64, seed: u64) -> TriSurface {
    let mut rng = Rng::new(seed);
    let spec: Vec<(Vector3<f64>, f64, f64)> = (0..bumps)
        .map(|k| {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            (rng.direction(), sign * rng.range(0.3, 1.0) * amplitude, rng.range(0.2, 0.5))
        })
        .collect();
    let mut s = sphere(n);
    for v in &mut s.vertices {
        let u = v.coords;
        let r: f64 = 1.0
            + spec
                .iter()
                .map(|(c, a, w)| a * (-(u - c).norm_squared() / (w * w)).exp())
                .sum::<f64>();
        *v = Point3::from(u * r);
    }
    s
}

/// Convex hull of `n` random points in the unit ball: sharp edges and corners, irregular
/// triangles.
pub fn random_convex(n: usize, seed: u64) -> TriSurface {
    let mut rng = Rng::new(seed);
    let pts: Vec<Point3<f64>> =
        (0..n).map(|_| Point3::from(rng.direction() * rng.range(0.5, 1.0))).collect();
    convex_hull(&pts)
}

/// Midpoint refinement: every triangle split into four; new vertices mapped by `project`
/// (e.g. back onto an ellipsoid). Keeps orientation.
pub fn refine(s: &TriSurface, project: impl Fn(Point3<f64>) -> Point3<f64>) -> TriSurface {
    let mut vertices = s.vertices.clone();
    let mut mid = std::collections::HashMap::new();
    let mut midpoint = |a: usize, b: usize, vertices: &mut Vec<Point3<f64>>| {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            vertices.push(project(nalgebra::center(&s.vertices[a], &s.vertices[b])));
            vertices.len() - 1
        })
    };
    let mut triangles = Vec::with_capacity(4 * s.triangles.len());
    for &[a, b, c] in &s.triangles {
        let ab = midpoint(a, b, &mut vertices);
        let bc = midpoint(b, c, &mut vertices);
        let ca = midpoint(c, a, &mut vertices);
        triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    TriSurface { vertices, triangles }
}

/// Maps a point radially onto the ellipsoid with semi-axes `radii` centred at the origin.
pub fn onto_ellipsoid(p: Point3<f64>, radii: Vector3<f64>) -> Point3<f64> {
    let q = p.coords.component_div(&radii);
    Point3::from(p.coords / q.norm())
}
