//! Shared helpers for the integration tests.
#![allow(dead_code)]

use bs_contact::MasterSurface;
use bs_contact::shapes::{self, Rng};
use bs_mesh::{Point3, TriSurface, Vector3};

/// Named closed test surfaces: ellipsoids at three refinements, non-convex bumpy spheres
/// (dents and ridges), random convex polyhedra (sharp edges, irregular triangles).
pub fn surfaces() -> Vec<(&'static str, TriSurface)> {
    let radii = Vector3::new(1.0, 0.8, 0.6);
    let coarse = shapes::ellipsoid(120, radii);
    let fine = shapes::refine(&coarse, |p| shapes::onto_ellipsoid(p, radii));
    vec![
        ("ellipsoid-120", coarse),
        ("ellipsoid-120x4", fine),
        ("ellipsoid-400", shapes::ellipsoid(400, radii)),
        ("bumpy-a", shapes::bumpy_sphere(500, 10, 0.25, 7)),
        ("bumpy-b", shapes::bumpy_sphere(400, 16, 0.3, 11)),
        ("convex-30", shapes::random_convex(30, 3)),
        ("convex-60", shapes::random_convex(60, 5)),
        ("convex-200", shapes::random_convex(200, 8)),
    ]
}

/// A random point of the surface (uniform face, uniform barycentric).
pub fn surface_point(m: &MasterSurface, rng: &mut Rng) -> Point3<f64> {
    let f = (rng.next_u64() % m.triangles().len() as u64) as usize;
    let t = m.triangles()[f];
    let (mut u, mut v) = (rng.uniform(), rng.uniform());
    if u + v > 1.0 {
        u = 1.0 - u;
        v = 1.0 - v;
    }
    let a = m.vertices()[t[0] as usize];
    a + (m.vertices()[t[1] as usize] - a) * u + (m.vertices()[t[2] as usize] - a) * v
}

/// A random query within `reach` of a random surface point, in a random direction (so
/// inside and outside in about equal numbers).
pub fn query_near(m: &MasterSurface, rng: &mut Rng, reach: f64) -> Point3<f64> {
    surface_point(m, rng) + rng.direction() * rng.range(0.0, reach)
}

/// Tolerance for comparing distances computed by different formulas for the same closest
/// point: 1e-9 relative, floored at 1e-12 of the model size (rounding of the coordinates is
/// ~1e-16 of the model size, so this floor is 10⁴ times above it and 10⁹ below any
/// geometric difference that matters).
pub fn tol(reference: f64, size: f64) -> f64 {
    1e-9 * reference.abs().max(1e-3 * size)
}

/// A unit cube [0,1]³, outward-oriented, 12 triangles (analytic distances).
pub fn cube() -> TriSurface {
    let v: Vec<Point3<f64>> = (0..8)
        .map(|i| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect();
    let quads = [
        [0, 2, 3, 1], // z = 0, normal −z
        [4, 5, 7, 6], // z = 1
        [0, 1, 5, 4], // y = 0
        [2, 6, 7, 3], // y = 1
        [0, 4, 6, 2], // x = 0
        [1, 3, 7, 5], // x = 1
    ];
    let mut triangles = Vec::new();
    for q in quads {
        triangles.push([q[0], q[1], q[2]]);
        triangles.push([q[0], q[2], q[3]]);
    }
    TriSurface { vertices: v, triangles }
}
