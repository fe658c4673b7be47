//! Resampling through the located lattice: every tetrahedron's linear interpolant of a
//! nodal point field, composed with an affine map (for example a second image's
//! world-to-index matrix), is one affine map of the lattice indices, `y = M ijk + b`.
//! Computed once per tetrahedron, it makes each lattice point nine multiply-adds instead of
//! barycentric weights, a four-node gather and a 4 × 4 transform.
//!
//! The map is the tetrahedron's linear interpolant continued beyond its faces: a lattice
//! point the location gave to a tetrahedron within [`INSIDE_TOLERANCE`](super::INSIDE_TOLERANCE)
//! of a face reads the continuation, where [`LatticeLocation::locate`] clamps its weights; the
//! two differ by that tolerance times the tetrahedron's size.

use nalgebra::{Matrix3, Matrix4, Point3, Vector3};
use rayon::prelude::*;

use super::{LatticeLocation, OUTSIDE};

/// `y = m · ijk + b`: a point field of one tetrahedron as a function of lattice indices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetAffine {
    /// The linear part.
    pub m: Matrix3<f64>,
    /// The offset.
    pub b: Vector3<f64>,
}

impl TetAffine {
    /// The map at lattice indices `ijk`.
    #[inline]
    pub fn apply(&self, ijk: [f64; 3]) -> [f64; 3] {
        let y = self.m * Vector3::new(ijk[0], ijk[1], ijk[2]) + self.b;
        [y.x, y.y, y.z]
    }

    /// This map minus the affine map `a` (its 3 × 4 upper part): e.g. the lattice's own
    /// index-to-world map, to turn positions into displacements.
    pub fn minus(&self, a: &Matrix4<f64>) -> TetAffine {
        let m = self.m - a.fixed_view::<3, 3>(0, 0);
        let b = self.b - a.fixed_view::<3, 1>(0, 3);
        TetAffine { m, b }
    }
}

impl LatticeLocation {
    /// Per tetrahedron: the affine map of lattice indices to `to` applied to the linear
    /// interpolant of `values` (one point per node), i.e. `Σ_c w_c(ijk) to(values[node c])`.
    pub fn affine_maps(&self, values: &[Point3<f64>], to: &Matrix4<f64>) -> Vec<TetAffine> {
        self.tets
            .par_iter()
            .zip(&self.inverse)
            .zip(&self.first)
            .map(|((tet, inv), q0)| {
                let s = tet.map(|n| to.transform_point(&values[n]).coords);
                let edges = Matrix3::from_columns(&[s[1] - s[0], s[2] - s[0], s[3] - s[0]]);
                // s(ijk) = s0 + E · inv · (ijk − q0).
                let m = edges * inv;
                TetAffine { m, b: s[0] - m * q0.coords }
            })
            .collect()
    }

    /// `keep` (all `T::default()` when `None`) with every lattice point inside the mesh
    /// replaced by `f(y)`, `y` the map of its tetrahedron in `maps` at its indices (where `f`
    /// has a value): in parallel over z slices, each copied and filled in one pass.
    pub fn map_inside<T, F>(&self, keep: Option<&[T]>, maps: &[TetAffine], f: F) -> Vec<T>
    where
        T: Copy + Send + Sync + Default,
        F: Fn([f64; 3]) -> Option<T> + Sync,
    {
        let [nx, ny, _] = self.dims;
        let plane = nx * ny;
        assert!(keep.is_none_or(|k| k.len() == self.owner.len()), "one value per lattice point");
        assert_eq!(maps.len(), self.tets.len(), "one map per tetrahedron");
        let mut out = vec![T::default(); self.owner.len()];
        out.par_chunks_mut(plane).zip(self.owner.par_chunks(plane)).enumerate().for_each(
            |(k, (out, owner))| {
                if let Some(keep) = keep {
                    out.copy_from_slice(&keep[k * plane..k * plane + out.len()]);
                }
                for (m, (o, &t)) in out.iter_mut().zip(owner).enumerate() {
                    if t == OUTSIDE {
                        continue;
                    }
                    let ijk = [(m % nx) as f64, (m / nx) as f64, k as f64];
                    if let Some(v) = f(maps[t as usize].apply(ijk)) {
                        *o = v;
                    }
                }
            },
        );
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::tetrahedra;
    use crate::structured::box_mesh;

    /// A sheared, scaled lattice-to-world matrix and its inverse.
    fn oblique() -> (Matrix4<f64>, Matrix4<f64>) {
        let to_world = Matrix4::new(
            0.9, 0.1, 0.0, -1.3, //
            0.0, 1.1, 0.2, 0.4, //
            0.05, 0.0, 0.8, 2.0, //
            0.0, 0.0, 0.0, 1.0,
        );
        (to_world, to_world.try_inverse().unwrap())
    }

    #[test]
    fn the_affine_map_equals_the_clamped_interpolant_inside_every_tetrahedron() {
        // A deformed Kuhn box on an oblique lattice; the field is an arbitrary nonlinear
        // function of the nodes, sent through a second affine map.
        let mut mesh = box_mesh(3, 6.0, true);
        for p in &mut mesh.nodes {
            *p += Vector3::new(0.1 * (p.y * 0.7).sin(), 0.15 * (p.z * 0.5).cos(), 0.05 * p.x);
        }
        let (tets, _) = tetrahedra(&mesh);
        let ids: Vec<u64> = (0..tets.len() as u64).collect();
        let (to_world, to_index) = oblique();
        let loc = LatticeLocation::new(&mesh.nodes, &tets, &ids, [9, 9, 9], &to_index).unwrap();
        let values: Vec<Point3<f64>> = mesh
            .nodes
            .iter()
            .map(|p| Point3::new(p.x * p.x, p.y + p.z, (p.x * p.y).cos()))
            .collect();
        let maps = loc.affine_maps(&values, &to_world);
        let mut checked = 0;
        for n in 0..loc.owners().len() {
            let Some((t, w)) = loc.locate(n) else { continue };
            let ijk = [n % 9, (n / 9) % 9, n / 81].map(|x| x as f64);
            let want = to_world.transform_point(&loc.interpolate(t, &w, &values));
            let got = maps[t].apply(ijk);
            for c in 0..3 {
                assert!((got[c] - want[c]).abs() < 1e-9, "point {n}: {got:?} vs {want:?}");
            }
            checked += 1;
        }
        assert!(checked > 100, "{checked} points inside");
    }

    #[test]
    fn map_inside_keeps_the_outside_and_maps_the_inside() {
        let mesh = box_mesh(2, 2.0, true);
        let (tets, _) = tetrahedra(&mesh);
        let ids: Vec<u64> = (0..tets.len() as u64).collect();
        // Lattice 5³ at unit spacing from −1: points 1..=3 per axis are inside the box [0, 2].
        let mut to_index = Matrix4::identity();
        to_index[(0, 3)] = 1.0;
        to_index[(1, 3)] = 1.0;
        to_index[(2, 3)] = 1.0;
        let loc = LatticeLocation::new(&mesh.nodes, &tets, &ids, [5, 5, 5], &to_index).unwrap();
        // The identity field in world coordinates: y = ijk − 1.
        let maps = loc.affine_maps(&mesh.nodes, &Matrix4::identity());
        let keep = vec![-7.0f64; 125];
        let out = loc.map_inside(Some(&keep), &maps, |y| Some(y[0] + 10.0 * y[1] + 100.0 * y[2]));
        for (n, got) in out.iter().enumerate() {
            let ijk = [n % 5, (n / 5) % 5, n / 25];
            let inside = ijk.iter().all(|&x| (1..=3).contains(&x));
            let want = if inside {
                (ijk[0] as f64 - 1.0) + 10.0 * (ijk[1] as f64 - 1.0) + 100.0 * (ijk[2] as f64 - 1.0)
            } else {
                -7.0
            };
            assert!((got - want).abs() < 1e-12, "point {ijk:?}: {got} vs {want}");
        }
    }
}
