//! Point location of a whole regular lattice (e.g. the voxel centres of an image) in a
//! tetrahedral mesh at once: the kernel of image warping and displacement-field export.
//!
//! [`TetLocator`](crate::TetLocator) answers one point at a time; an image has millions of
//! voxel centres, most of them outside the brain. Here every tetrahedron is *rasterised*
//! instead: its corners are taken to continuous lattice indices (the lattice's
//! world-to-index affine), and the lattice points inside its index-space bounding box are
//! tested with its barycentric coordinates. Barycentric coordinates are invariant under
//! affine maps, so the weights found in index space are the weights in world space. Only
//! lattice points inside some tetrahedron's bounding box are ever visited.
//!
//! The work runs in parallel over z slices of the lattice (each slice owns its part of the
//! output; the tetrahedra crossing a slice are listed once, in element order). A lattice
//! point on a face shared by two tetrahedra (or within [`INSIDE_TOLERANCE`] of it, in
//! barycentric units) belongs to the one of lowest index, so the result does not depend on
//! the number of threads.

use nalgebra::{Matrix3, Matrix4, Point3};
use rayon::prelude::*;

use crate::{ElementKind, LocateError, Mesh};

mod affine;
pub use affine::TetAffine;

/// A lattice point whose barycentric weights are all ≥ −`INSIDE_TOLERANCE` counts as inside
/// the tetrahedron: points on a shared face (exactly, in exact arithmetic) read about −1e-16
/// in both neighbours after rounding and must not fall into a crack between them.
pub const INSIDE_TOLERANCE: f64 = 1e-10;

/// The owner of a lattice point inside no tetrahedron.
pub const OUTSIDE: u32 = u32::MAX;

/// The six tetrahedra of a hexahedron (Abaqus/VTK node order) around its diagonal 0–6, the
/// split of [`structured::box_mesh`](crate::structured::box_mesh): positively oriented for a
/// positively oriented hex, and conforming between neighbouring hexes of a structured grid
/// (their shared faces are cut along the same diagonal).
pub const HEX_TO_TETS: [[usize; 4]; 6] =
    [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]];

/// The mesh as tetrahedra: T4 elements as they are, H8 elements split by [`HEX_TO_TETS`].
/// Returns the node indices of every tetrahedron and the index of the element it came from.
///
/// For hexahedra the piecewise-linear map on the split interpolates the trilinear element
/// map exactly at the nodes only (a deformed hex face is not planar): a lattice point is
/// located in the tetrahedra, which is the inverse of the piecewise-linear interpolant of the
/// result. Unstructured hex meshes whose neighbours cut a shared face along different
/// diagonals leave thin cracks or overlaps there; points in a crack count as outside.
pub fn tetrahedra(mesh: &Mesh) -> (Vec<[usize; 4]>, Vec<usize>) {
    let mut tets = Vec::with_capacity(mesh.elements.len());
    let mut source = Vec::with_capacity(mesh.elements.len());
    for (e, el) in mesh.elements.iter().enumerate() {
        let n = el.nodes();
        match el.kind() {
            ElementKind::Tet4 => {
                tets.push([n[0], n[1], n[2], n[3]]);
                source.push(e);
            }
            ElementKind::Hex8 => {
                for t in HEX_TO_TETS {
                    tets.push(t.map(|q| n[q]));
                    source.push(e);
                }
            }
        }
    }
    (tets, source)
}

/// Which tetrahedron contains each point of a regular lattice.
#[derive(Debug, Clone)]
pub struct LatticeLocation {
    dims: [usize; 3],
    /// Per lattice point (first index fastest): the containing tetrahedron, or [`OUTSIDE`].
    owner: Vec<u32>,
    tets: Vec<[usize; 4]>,
    /// Per tetrahedron: its first corner in lattice indices and the inverse of
    /// [q1 − q0, q2 − q0, q3 − q0] (index space).
    first: Vec<Point3<f64>>,
    inverse: Vec<Matrix3<f64>>,
}

impl LatticeLocation {
    /// Locates every point of the lattice of `dims` points at integer indices (i, j, k)
    /// (world position `world_to_index⁻¹ (i, j, k)`) in the tetrahedra `tets` of `nodes`
    /// (world coordinates). `ids[t]` is the id users know tetrahedron `t` by (its element's
    /// file id), for error messages.
    pub fn new(
        nodes: &[Point3<f64>],
        tets: &[[usize; 4]],
        ids: &[u64],
        dims: [usize; 3],
        world_to_index: &Matrix4<f64>,
    ) -> Result<Self, LocateError> {
        if tets.is_empty() {
            return Err(LocateError::Empty);
        }
        if tets.len() >= OUTSIDE as usize {
            return Err(LocateError::TooLarge { tetrahedra: tets.len() });
        }
        let id = |t: usize| ids.get(t).copied().unwrap_or(t as u64);
        // Per tet, in parallel: its first corner and inverse edge matrix in lattice
        // coordinates, and the lattice index range of its bounding box (empty when outside).
        type Setup = (Point3<f64>, Matrix3<f64>, [(usize, usize); 3]);
        let setup: Vec<Result<Setup, LocateError>> = tets
            .par_iter()
            .enumerate()
            .map(|(t, tet)| {
                let mut q = [Point3::origin(); 4];
                for c in 0..4 {
                    let p = nodes.get(tet[c]).ok_or(LocateError::Degenerate { id: id(t) })?;
                    q[c] = world_to_index.transform_point(p);
                    if !q[c].coords.iter().all(|x| x.is_finite()) {
                        return Err(LocateError::NonFinite { id: id(t) });
                    }
                }
                let m = Matrix3::from_columns(&[q[1] - q[0], q[2] - q[0], q[3] - q[0]]);
                let scale =
                    (q[1] - q[0]).norm().max((q[2] - q[0]).norm()).max((q[3] - q[0]).norm());
                let det = m.determinant();
                let inv = m
                    .try_inverse()
                    .filter(|_| det.abs() > 1e-14 * scale * scale * scale)
                    .ok_or(LocateError::Degenerate { id: id(t) })?;
                let mut range = [(1usize, 0usize); 3];
                for a in 0..3 {
                    let lo = q.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min);
                    let hi = q.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max);
                    // Lattice points within the box, widened by a hair for points on its faces.
                    let pad = 1e-9 * (hi - lo).max(1.0);
                    let lo = (lo - pad).ceil().max(0.0);
                    let hi = (hi + pad).floor().min((dims[a] as f64) - 1.0);
                    if lo <= hi {
                        range[a] = (lo as usize, hi as usize);
                    }
                }
                Ok((q[0], inv, range))
            })
            .collect();
        // The first bad tetrahedron in element order, whatever the threads.
        let setup: Vec<Setup> = setup.into_iter().collect::<Result<_, _>>()?;
        let first: Vec<Point3<f64>> = setup.iter().map(|s| s.0).collect();
        let inverse: Vec<Matrix3<f64>> = setup.iter().map(|s| s.1).collect();
        let ranges: Vec<[(usize, usize); 3]> = setup.iter().map(|s| s.2).collect();
        drop(setup);
        // Tetrahedra per z slice (CSR, element order).
        let nz = dims[2];
        let mut count = vec![0usize; nz + 1];
        for r in &ranges {
            if r.iter().all(|&(lo, hi)| lo <= hi) {
                for k in r[2].0..=r[2].1 {
                    count[k + 1] += 1;
                }
            }
        }
        for k in 0..nz {
            count[k + 1] += count[k];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; count[nz]];
        for (t, r) in ranges.iter().enumerate() {
            if r.iter().all(|&(lo, hi)| lo <= hi) {
                for k in r[2].0..=r[2].1 {
                    items[fill[k]] = t as u32;
                    fill[k] += 1;
                }
            }
        }
        let [nx, ny, _] = dims;
        // Zeroed lazily by the allocator; each slice is filled by the thread that rasterises
        // it (the pages are first touched in parallel, and once).
        let mut owner = vec![0u32; nx * ny * nz];
        owner.par_chunks_mut(nx * ny).enumerate().for_each(|(k, slice)| {
            slice.fill(OUTSIDE);
            let z = k as f64;
            for &t in &items[count[k]..count[k + 1]] {
                let t = t as usize;
                let (inv, q0) = (&inverse[t], &first[t]);
                let r = &ranges[t];
                // Along a row the coordinates are affine in i, l(i) = l(i₀) + (i − i₀) inv·eₓ:
                // three multiply-adds per point instead of a 3 × 3 product.
                let step = inv.column(0).into_owned();
                for j in r[1].0..=r[1].1 {
                    let row = &mut slice[j * nx..(j + 1) * nx];
                    let i0 = r[0].0;
                    let start =
                        inv * nalgebra::Vector3::new(i0 as f64 - q0.x, j as f64 - q0.y, z - q0.z);
                    for (i, cell) in row.iter_mut().enumerate().take(r[0].1 + 1).skip(i0) {
                        let l = start + step * (i - i0) as f64;
                        let w0 = 1.0 - l.x - l.y - l.z;
                        // Without branches (`&`, a select): whether a point is inside is a
                        // coin toss the branch predictor loses about half the time.
                        let take = (*cell == OUTSIDE)
                            & (w0 >= -INSIDE_TOLERANCE)
                            & (l.x >= -INSIDE_TOLERANCE)
                            & (l.y >= -INSIDE_TOLERANCE)
                            & (l.z >= -INSIDE_TOLERANCE);
                        *cell = if take { t as u32 } else { *cell };
                    }
                }
            }
        });
        Ok(LatticeLocation { dims, owner, tets: tets.to_vec(), first, inverse })
    }

    /// The lattice size.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Per lattice point `i + nx (j + ny k)`: the containing tetrahedron or [`OUTSIDE`].
    pub fn owners(&self) -> &[u32] {
        &self.owner
    }

    /// Number of lattice points inside the mesh.
    pub fn inside_count(&self) -> usize {
        self.owner.iter().filter(|&&o| o != OUTSIDE).count()
    }

    /// Node indices of tetrahedron `t`.
    pub fn tet_nodes(&self, t: usize) -> [usize; 4] {
        self.tets[t]
    }

    /// The tetrahedron containing lattice point `n` and the barycentric weights of its four
    /// nodes there (non-negative, sum 1); `None` outside the mesh.
    pub fn locate(&self, n: usize) -> Option<(usize, [f64; 4])> {
        let t = *self.owner.get(n)?;
        if t == OUTSIDE {
            return None;
        }
        let [nx, ny, _] = self.dims;
        let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
        Some((t as usize, self.weights(t as usize, [i, j, k])))
    }

    /// The barycentric coordinates of lattice point `ijk` in tetrahedron `t`, not clamped:
    /// negative outside it (the tetrahedron's affine map extended beyond its faces).
    pub fn barycentric(&self, t: usize, ijk: [usize; 3]) -> [f64; 4] {
        let q0 = &self.first[t];
        let d = nalgebra::Vector3::new(
            ijk[0] as f64 - q0.x,
            ijk[1] as f64 - q0.y,
            ijk[2] as f64 - q0.z,
        );
        let l = self.inverse[t] * d;
        [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
    }

    fn weights(&self, t: usize, ijk: [usize; 3]) -> [f64; 4] {
        let q0 = &self.first[t];
        let d = nalgebra::Vector3::new(
            ijk[0] as f64 - q0.x,
            ijk[1] as f64 - q0.y,
            ijk[2] as f64 - q0.z,
        );
        let l = self.inverse[t] * d;
        let w = [1.0 - l.x - l.y - l.z, l.x, l.y, l.z].map(|x| x.max(0.0));
        let s: f64 = w.iter().sum();
        w.map(|x| x / s)
    }

    /// `Σ w_c values[node c]`: a nodal quantity interpolated in tetrahedron `t`.
    pub fn interpolate_scalar(&self, t: usize, weights: &[f64; 4], values: &[f64]) -> f64 {
        self.tets[t].iter().zip(weights).map(|(&a, w)| values[a] * w).sum()
    }

    /// The point of `values` (one per node) at barycentric `weights` in tetrahedron `t`.
    pub fn interpolate(&self, t: usize, weights: &[f64; 4], values: &[Point3<f64>]) -> Point3<f64> {
        let n = self.tets[t];
        Point3::from(
            values[n[0]].coords * weights[0]
                + values[n[1]].coords * weights[1]
                + values[n[2]].coords * weights[2]
                + values[n[3]].coords * weights[3],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::structured::box_mesh;

    fn identity() -> Matrix4<f64> {
        Matrix4::identity()
    }

    #[test]
    fn every_lattice_point_of_a_kuhn_box_is_found_once_with_exact_weights() {
        // A 4×4×4 Kuhn box of size 4 has its nodes on the lattice: lattice points lie on
        // vertices, edges and faces of many tets at once, the worst case for ties.
        let mesh = box_mesh(4, 4.0, true);
        let (tets, _) = tetrahedra(&mesh);
        let ids: Vec<u64> = (0..tets.len() as u64).collect();
        let loc = LatticeLocation::new(&mesh.nodes, &tets, &ids, [7, 7, 7], &identity()).unwrap();
        // Points 0..=4 on each axis are inside (closed box), 5 and 6 outside.
        assert_eq!(loc.inside_count(), 125);
        for k in 0..7 {
            for j in 0..7 {
                for i in 0..7 {
                    let n = i + 7 * (j + 7 * k);
                    let inside = i <= 4 && j <= 4 && k <= 4;
                    match loc.locate(n) {
                        None => assert!(!inside, "({i},{j},{k})"),
                        Some((t, w)) => {
                            assert!(inside);
                            // The weights reproduce the point (a linear field) to rounding.
                            let p = loc.interpolate(t, &w, &mesh.nodes);
                            let e = (p - Point3::new(i as f64, j as f64, k as f64)).norm();
                            assert!(e < 1e-12, "({i},{j},{k}): {e}");
                            // Ties go to the lowest tetrahedron index that contains it.
                            let lowest = (0..tets.len())
                                .find(|&s| {
                                    let m = Matrix3::from_columns(&[
                                        mesh.nodes[tets[s][1]] - mesh.nodes[tets[s][0]],
                                        mesh.nodes[tets[s][2]] - mesh.nodes[tets[s][0]],
                                        mesh.nodes[tets[s][3]] - mesh.nodes[tets[s][0]],
                                    ]);
                                    let l = m.try_inverse().unwrap()
                                        * (Point3::new(i as f64, j as f64, k as f64)
                                            - mesh.nodes[tets[s][0]]);
                                    [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
                                        .iter()
                                        .all(|&x| x >= -INSIDE_TOLERANCE)
                                })
                                .unwrap();
                            assert_eq!(t, lowest);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn an_oblique_lattice_agrees_with_brute_force_location() {
        // Lattice spacing 0.61 with a rotation and an offset, a jittered mesh: every point
        // tested against every tetrahedron (the reference), away from faces by design.
        let mesh = crate::structured::jittered_box_mesh(4, 10.0, true, 0.2, 7);
        let (tets, _) = tetrahedra(&mesh);
        let ids: Vec<u64> = (0..tets.len() as u64).collect();
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.5);
        let mut to_world = Matrix4::identity();
        to_world.fixed_view_mut::<3, 3>(0, 0).copy_from(&(rot.matrix() * 0.61));
        to_world[(0, 3)] = -1.3;
        to_world[(1, 3)] = 0.7;
        to_world[(2, 3)] = -2.1;
        let dims = [24, 22, 25];
        let inv = to_world.try_inverse().unwrap();
        let loc = LatticeLocation::new(&mesh.nodes, &tets, &ids, dims, &inv).unwrap();
        let inverses: Vec<(Point3<f64>, Matrix3<f64>)> = tets
            .iter()
            .map(|t| {
                let c = t.map(|n| mesh.nodes[n]);
                let m = Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]]);
                (c[0], m.try_inverse().unwrap())
            })
            .collect();
        let bary = |t: usize, p: &Point3<f64>| {
            let l = inverses[t].1 * (p - inverses[t].0);
            [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
        };
        let mut inside = 0;
        for n in 0..dims[0] * dims[1] * dims[2] {
            let (i, j, k) = (n % 24, (n / 24) % 22, n / (24 * 22));
            let p = to_world.transform_point(&Point3::new(i as f64, j as f64, k as f64));
            // The lowest tetrahedron containing p (within the tolerance), by brute force.
            let reference =
                (0..tets.len()).find(|&t| bary(t, &p).iter().all(|&w| w >= -INSIDE_TOLERANCE));
            match loc.locate(n) {
                Some((t, w)) => {
                    inside += 1;
                    assert_eq!(Some(t), reference, "{n}");
                    let q = loc.interpolate(t, &w, &mesh.nodes);
                    assert!((q - p).norm() < 1e-9, "{n}");
                }
                None => assert_eq!(reference, None, "{n}: {p}"),
            }
        }
        assert!(inside > 1000, "{inside}");
    }

    #[test]
    fn hexahedra_are_split_into_six_positive_tetrahedra() {
        let hexes = box_mesh(2, 2.0, false);
        let (tets, source) = tetrahedra(&hexes);
        assert_eq!(tets.len(), 48);
        assert_eq!(source[47], 7);
        let total: f64 = tets
            .iter()
            .map(|t| {
                let p = t.map(|n| hexes.nodes[n]);
                Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]).determinant() / 6.0
            })
            .inspect(|&v| assert!(v > 0.0))
            .sum();
        // The 2 × 2 × 2 box: volume 8.
        assert!((total - 8.0).abs() < 1e-12);
    }

    #[test]
    fn degenerate_and_non_finite_tetrahedra_are_errors_naming_them() {
        let nodes = [[0., 0., 0.], [1., 0., 0.], [2., 0., 0.], [0., 1., 0.]].map(Point3::from);
        let e = LatticeLocation::new(&nodes, &[[0, 1, 2, 3]], &[42], [2, 2, 2], &identity())
            .unwrap_err();
        assert_eq!(e, LocateError::Degenerate { id: 42 });
        let nodes =
            [[0., 0., 0.], [1., 0., 0.], [0., f64::NAN, 0.], [0., 0., 1.]].map(Point3::from);
        let e = LatticeLocation::new(&nodes, &[[0, 1, 2, 3]], &[7], [2, 2, 2], &identity())
            .unwrap_err();
        assert_eq!(e, LocateError::NonFinite { id: 7 });
    }
}
