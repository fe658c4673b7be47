//! Which points of a regular lattice (an image's voxel centres) lie inside a closed triangle
//! surface (e.g. the skull cavity), all at once: the inside of a surface rasterised by
//! parity along the lattice's rows.
//!
//! The surface's vertices are taken to continuous lattice indices (the lattice's
//! world-to-index affine). Every lattice row (j, k) is a line along i; a point of the row is
//! inside when the row crosses the surface an odd number of times before it. Each triangle
//! adds its crossing to the rows that pass through its (j, k) shadow. The rows are offset by
//! a tiny irrational-looking amount ([`ROW_OFFSET`], far below any voxel) so that no row
//! passes exactly through a vertex or an edge of a surface whose vertices sit on lattice
//! planes; a crossing is then counted exactly once. The work runs in parallel over z slices;
//! the answer does not depend on the number of threads.

use nalgebra::{Matrix4, Point3};
use rayon::prelude::*;

/// The (j, k) offset of every row, in lattice units: generic, so rows miss vertices and
/// edges of surfaces whose vertices lie on lattice planes.
pub const ROW_OFFSET: [f64; 2] = [1.234_567_9e-7, 2.718_281_8e-7];

/// For every lattice point (first index fastest, `dims` points), whether it lies inside the
/// closed surface of `vertices` and `triangles` (world coordinates; the lattice point
/// (i, j, k) is at `world_to_index⁻¹ (i, j, k)`). A surface that is not closed gives
/// rows with an odd number of crossings; those rows count as outside past their last
/// crossing, as parity says.
pub fn inside_closed_surface(
    vertices: &[Point3<f64>],
    triangles: &[[usize; 3]],
    dims: [usize; 3],
    world_to_index: &Matrix4<f64>,
) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let q: Vec<Point3<f64>> = vertices.iter().map(|p| world_to_index.transform_point(p)).collect();
    // Triangles per z slice whose (j, k) shadow contains a row of that slice.
    let mut per_slice: Vec<Vec<u32>> = vec![Vec::new(); nz];
    for (t, tri) in triangles.iter().enumerate() {
        let Some(c) = corners(&q, tri) else { continue };
        let lo = c.iter().map(|p| p.z).fold(f64::INFINITY, f64::min) - ROW_OFFSET[1];
        let hi = c.iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max) - ROW_OFFSET[1];
        let (lo, hi) = (lo.ceil().max(0.0), hi.floor().min(nz as f64 - 1.0));
        if lo <= hi {
            for slice in &mut per_slice[lo as usize..=hi as usize] {
                slice.push(t as u32);
            }
        }
    }
    let mut inside = vec![false; nx * ny * nz];
    inside.par_chunks_mut(nx * ny).enumerate().for_each(|(k, slice)| {
        let z = k as f64 + ROW_OFFSET[1];
        // Crossings per row j: the i coordinate where the row meets a triangle.
        let mut rows: Vec<Vec<f64>> = vec![Vec::new(); ny];
        for &t in &per_slice[k] {
            let Some(c) = corners(&q, &triangles[t as usize]) else { continue };
            let lo = c.iter().map(|p| p.y).fold(f64::INFINITY, f64::min) - ROW_OFFSET[0];
            let hi = c.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max) - ROW_OFFSET[0];
            let (lo, hi) = (lo.ceil().max(0.0), hi.floor().min(ny as f64 - 1.0));
            if lo > hi {
                continue;
            }
            for (j, row) in rows.iter_mut().enumerate().take(hi as usize + 1).skip(lo as usize) {
                if let Some(x) = crossing(&c, j as f64 + ROW_OFFSET[0], z) {
                    row.push(x);
                }
            }
        }
        for (j, xs) in rows.iter_mut().enumerate() {
            if xs.len() < 2 {
                continue;
            }
            xs.sort_by(f64::total_cmp);
            let row = &mut slice[j * nx..(j + 1) * nx];
            for pair in xs.chunks_exact(2) {
                let a = pair[0].ceil().max(0.0);
                let b = pair[1].floor().min(nx as f64 - 1.0);
                if a <= b {
                    row[a as usize..=b as usize].iter_mut().for_each(|v| *v = true);
                }
            }
        }
    });
    inside
}

fn corners(q: &[Point3<f64>], tri: &[usize; 3]) -> Option<[Point3<f64>; 3]> {
    Some([*q.get(tri[0])?, *q.get(tri[1])?, *q.get(tri[2])?])
}

/// Where the line {(x, y, z) : x ∈ ℝ} crosses the triangle `c`, or `None` when it misses
/// (or the triangle is parallel to it).
fn crossing(c: &[Point3<f64>; 3], y: f64, z: f64) -> Option<f64> {
    // Barycentric coordinates of (y, z) in the triangle's (y, z) projection.
    let (y0, z0) = (c[0].y, c[0].z);
    let (e1y, e1z) = (c[1].y - y0, c[1].z - z0);
    let (e2y, e2z) = (c[2].y - y0, c[2].z - z0);
    let det = e1y * e2z - e1z * e2y;
    if det == 0.0 {
        return None;
    }
    let (py, pz) = (y - y0, z - z0);
    let l1 = (py * e2z - pz * e2y) / det;
    let l2 = (e1y * pz - e1z * py) / det;
    let l0 = 1.0 - l1 - l2;
    if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
        return None;
    }
    Some(l0 * c[0].x + l1 * c[1].x + l2 * c[2].x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An icosphere-like closed surface: a UV sphere of `r` at `c`.
    fn sphere(c: Point3<f64>, r: f64, n: usize) -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
        let mut v = vec![c + nalgebra::Vector3::new(0.0, 0.0, r)];
        for a in 1..n {
            let th = std::f64::consts::PI * a as f64 / n as f64;
            for b in 0..2 * n {
                let ph = std::f64::consts::PI * b as f64 / n as f64;
                v.push(
                    c + r * nalgebra::Vector3::new(
                        th.sin() * ph.cos(),
                        th.sin() * ph.sin(),
                        th.cos(),
                    ),
                );
            }
        }
        v.push(c - nalgebra::Vector3::new(0.0, 0.0, r));
        let ring = |a: usize, b: usize| 1 + (a - 1) * 2 * n + b % (2 * n);
        let mut t = Vec::new();
        for b in 0..2 * n {
            t.push([0, ring(1, b), ring(1, b + 1)]);
            t.push([v.len() - 1, ring(n - 1, b + 1), ring(n - 1, b)]);
        }
        for a in 1..n - 1 {
            for b in 0..2 * n {
                t.push([ring(a, b), ring(a + 1, b), ring(a + 1, b + 1)]);
                t.push([ring(a, b), ring(a + 1, b + 1), ring(a, b + 1)]);
            }
        }
        (v, t)
    }

    #[test]
    fn a_box_with_vertices_on_lattice_points_is_filled_exactly() {
        // The closed boundary of a structured box whose corners are lattice points: the
        // worst case for rows through vertices and edges (the offset rows pass just inside
        // the lower faces j = 0 and k = 0 and just outside the upper ones).
        let mesh = crate::structured::box_mesh(3, 6.0, true);
        let b = mesh.boundary();
        let inside = inside_closed_surface(
            &b.surface.vertices,
            &b.surface.triangles,
            [10, 10, 10],
            &Matrix4::identity(),
        );
        for k in 0..10 {
            for j in 0..10 {
                for i in 0..10 {
                    // Rows sit at j + ε, k + ε: inside ⇔ 0 ≤ j < 6, 0 ≤ k < 6 and 0 < i < 6;
                    // points on the faces i = 0 and i = 6 lie on the surface (either answer).
                    if i == 0 || i == 6 {
                        continue;
                    }
                    let expect = j < 6 && k < 6 && i < 6;
                    assert_eq!(inside[i + 10 * (j + 10 * k)], expect, "({i},{j},{k})");
                }
            }
        }
    }

    #[test]
    fn a_sphere_on_an_oblique_lattice_agrees_with_the_distance_test() {
        let (v, t) = sphere(Point3::new(0.3, -0.2, 0.1), 7.0, 48);
        let rot = nalgebra::Rotation3::from_euler_angles(0.4, -0.3, 0.2);
        let mut to_world = Matrix4::identity();
        to_world.fixed_view_mut::<3, 3>(0, 0).copy_from(&(rot.matrix() * 0.7));
        for a in 0..3 {
            to_world[(a, 3)] = -10.0;
        }
        let dims = [30, 30, 30];
        let inside = inside_closed_surface(&v, &t, dims, &to_world.try_inverse().unwrap());
        let mut wrong = 0;
        for (n, &got) in inside.iter().enumerate() {
            let (i, j, k) = (n % 30, (n / 30) % 30, n / 900);
            let p = to_world.transform_point(&Point3::new(i as f64, j as f64, k as f64));
            let r = (p - Point3::new(0.3, -0.2, 0.1)).norm();
            // The polygonal sphere lies within 7 (1 − cos(π/48)) ≈ 0.015 of the round one.
            if (r - 7.0).abs() > 0.02 {
                wrong += usize::from(got != (r < 7.0));
            }
        }
        assert_eq!(wrong, 0);
    }
}
