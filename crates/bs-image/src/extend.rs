//! A vector field extended harmonically into part of a grid: the discrete Laplace equation
//! Δd = 0 on the *free* voxels, with the values of every other voxel as Dirichlet data and
//! zero normal derivative at the grid's edges. This is how brainshift carries the brain's
//! displacement into the space between brain and skull (the free voxels): equal to the
//! finite-element inverse map inside the brain, zero at the rigid skull and beyond, smooth
//! in between. In one dimension the harmonic extension is the linear stretch of the gap, so
//! the map y ↦ y + d(y) stays monotone while the gap keeps a positive width.
//!
//! The Laplacian is the 7-point stencil in voxel index space weighted by 1/h² per axis
//! (h the voxel size along that axis): exact for anisotropic and rotated (oblique) grids,
//! whose axes are orthogonal; a sheared grid's cross terms are left out (the extension
//! stays harmonic to first order, which is all it needs to be). The three components share
//! the operator and are solved together by conjugate gradients with a diagonal (Jacobi)
//! preconditioner, on the free voxels only; every reduction is summed in fixed chunks, so
//! the result does not depend on the number of threads.
//!
//! [`jacobian`] measures whether the extended map folds: det(I + ∇d) by central differences
//! on the free voxels (≤ 0 where the map y ↦ y + d(y) is not locally invertible).

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::Grid;

/// Stopping rule and budget of [`harmonic_extension`].
#[derive(Debug, Clone, Copy)]
pub struct ExtensionParams {
    /// Stop when every component's residual norm is below `tolerance` times its right-hand
    /// side's norm.
    pub tolerance: f64,
    /// Conjugate-gradient iterations at most.
    pub max_iterations: usize,
}

impl Default for ExtensionParams {
    fn default() -> Self {
        ExtensionParams { tolerance: 1e-7, max_iterations: 20_000 }
    }
}

/// A field extended onto the free voxels.
#[derive(Debug, Clone)]
pub struct Extended {
    /// The free voxels (linear indices `i + nx (j + ny k)`, ascending).
    pub voxels: Vec<u32>,
    /// The extended field at each of them.
    pub values: Vec<[f64; 3]>,
    /// Conjugate-gradient iterations used.
    pub iterations: usize,
    /// Largest relative residual of the three components at the end.
    pub residual: f64,
}

/// Per free voxel: the free indices of its six neighbours (`u32::MAX`: fixed or off-grid).
const NONE: u32 = u32::MAX;

/// Chunk of the fixed-order reductions.
const CHUNK: usize = 4096;

/// Solves Δd = 0 on the voxels where `free` is true. `fixed(n)` gives the Dirichlet value of
/// voxel `n` (called only for non-free neighbours of free voxels, possibly from several
/// threads; a trait object, so that the solver is compiled, optimised, once here).
/// Neighbours beyond the grid's edge contribute nothing (zero normal derivative).
pub fn harmonic_extension(
    grid: &Grid,
    free: &[bool],
    fixed: &(dyn Fn(usize) -> [f64; 3] + Sync),
    params: &ExtensionParams,
) -> Extended {
    assert_eq!(free.len(), grid.len(), "one flag per voxel");
    let [nx, ny, nz] = grid.dims();
    let voxels: Vec<u32> =
        free.iter().enumerate().filter(|(_, f)| **f).map(|(n, _)| n as u32).collect();
    let m = voxels.len();
    if m == 0 {
        return Extended { voxels, values: Vec::new(), iterations: 0, residual: 0.0 };
    }
    // Axis weights 1/h².
    let h = grid.spacing();
    let w = [1.0 / (h[0] * h[0]), 1.0 / (h[1] * h[1]), 1.0 / (h[2] * h[2])];
    let stride = [1isize, nx as isize, (nx * ny) as isize];
    // Free voxel → its position in `voxels`: binary search in the sorted list.
    let slot = |n: usize| voxels.binary_search(&(n as u32)).ok().map(|s| s as u32);
    // Neighbour table, diagonal and right-hand side.
    let setup: Vec<([u32; 6], f64, [f64; 3])> = voxels
        .par_iter()
        .map(|&v| {
            let n = v as usize;
            let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
            let dims = [nx, ny, nz];
            let mut nb = [NONE; 6];
            let mut diag = 0.0;
            let mut rhs = [0.0; 3];
            for a in 0..3 {
                for (s, dir) in [(0usize, -1isize), (1, 1)] {
                    let inside = if dir < 0 { ijk[a] > 0 } else { ijk[a] + 1 < dims[a] };
                    if !inside {
                        continue;
                    }
                    let q = (n as isize + dir * stride[a]) as usize;
                    diag += w[a];
                    if free[q] {
                        nb[2 * a + s] = slot(q).unwrap_or(NONE);
                    } else {
                        let f = fixed(q);
                        for c in 0..3 {
                            rhs[c] += w[a] * f[c];
                        }
                    }
                }
            }
            (nb, diag, rhs)
        })
        .collect();
    let apply = |x: &[[f64; 3]], y: &mut [[f64; 3]]| {
        y.par_iter_mut().zip(setup.par_iter()).zip(x.par_iter()).for_each(
            |((y, (nb, diag, _)), xi)| {
                let mut acc = [diag * xi[0], diag * xi[1], diag * xi[2]];
                for (a, &q) in nb.iter().enumerate() {
                    if q != NONE {
                        let wq = w[a / 2];
                        let xq = &x[q as usize];
                        for c in 0..3 {
                            acc[c] -= wq * xq[c];
                        }
                    }
                }
                *y = acc;
            },
        );
    };
    let dot = |a: &[[f64; 3]], b: &[[f64; 3]]| -> [f64; 3] {
        let parts: Vec<[f64; 3]> = a
            .par_chunks(CHUNK)
            .zip(b.par_chunks(CHUNK))
            .map(|(a, b)| {
                let mut s = [0.0; 3];
                for (x, y) in a.iter().zip(b) {
                    for c in 0..3 {
                        s[c] += x[c] * y[c];
                    }
                }
                s
            })
            .collect();
        parts.iter().fold([0.0; 3], |s, p| [s[0] + p[0], s[1] + p[1], s[2] + p[2]])
    };
    let b: Vec<[f64; 3]> = setup.iter().map(|s| s.2).collect();
    let inv_diag: Vec<f64> = setup.iter().map(|s| 1.0 / s.1).collect();
    let b_norm = dot(&b, &b).map(f64::sqrt);
    // x₀ = D⁻¹ b (the first Jacobi step), r = b − A x₀.
    let mut x: Vec<[f64; 3]> =
        b.iter().zip(&inv_diag).map(|(b, d)| [b[0] * d, b[1] * d, b[2] * d]).collect();
    let mut ax = vec![[0.0; 3]; m];
    apply(&x, &mut ax);
    let mut r: Vec<[f64; 3]> =
        b.iter().zip(&ax).map(|(b, a)| [b[0] - a[0], b[1] - a[1], b[2] - a[2]]).collect();
    let precondition = |r: &[[f64; 3]], z: &mut [[f64; 3]]| {
        z.par_iter_mut().zip(r.par_iter()).zip(inv_diag.par_iter()).for_each(|((z, r), d)| {
            *z = [r[0] * d, r[1] * d, r[2] * d];
        });
    };
    let mut z = vec![[0.0; 3]; m];
    precondition(&r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut ap = ax;
    let relative = |r: &[[f64; 3]]| {
        let rn = dot(r, r).map(f64::sqrt);
        (0..3).map(|c| if b_norm[c] > 0.0 { rn[c] / b_norm[c] } else { rn[c] }).fold(0.0, f64::max)
    };
    let mut residual = relative(&r);
    let mut iterations = 0;
    while residual > params.tolerance && iterations < params.max_iterations {
        apply(&p, &mut ap);
        let pap = dot(&p, &ap);
        let alpha = [0, 1, 2].map(|c| if pap[c] > 0.0 { rz[c] / pap[c] } else { 0.0 });
        x.par_iter_mut().zip(r.par_iter_mut()).zip(p.par_iter().zip(ap.par_iter())).for_each(
            |((x, r), (p, ap))| {
                for c in 0..3 {
                    x[c] += alpha[c] * p[c];
                    r[c] -= alpha[c] * ap[c];
                }
            },
        );
        precondition(&r, &mut z);
        let rz_new = dot(&r, &z);
        let beta = [0, 1, 2].map(|c| if rz[c] > 0.0 { rz_new[c] / rz[c] } else { 0.0 });
        rz = rz_new;
        p.par_iter_mut().zip(z.par_iter()).for_each(|(p, z)| {
            for c in 0..3 {
                p[c] = z[c] + beta[c] * p[c];
            }
        });
        iterations += 1;
        residual = relative(&r);
    }
    Extended { voxels, values: x, iterations, residual }
}

/// How much a map y ↦ y + d(y) folds on a set of voxels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Folding {
    /// Voxels measured.
    pub voxels: usize,
    /// Voxels where det(I + ∇d) ≤ 0.
    pub non_positive: usize,
    /// Smallest det(I + ∇d) (1 when no voxel was measured).
    pub min: f64,
}

/// det(I + ∇d) at each of `voxels`, by central differences of `d` (one-sided at the grid's
/// edges) taken to world coordinates through the grid's affine; `d(n)` is the field at voxel
/// `n` (world frame, mm).
pub fn jacobian(grid: &Grid, voxels: &[u32], d: &(dyn Fn(usize) -> [f64; 3] + Sync)) -> Folding {
    let [nx, ny, nz] = grid.dims();
    let dims = [nx, ny, nz];
    let stride = [1usize, nx, nx * ny];
    // ∂(ijk)/∂y: the world-to-voxel affine's linear part.
    let to_index: Matrix3<f64> = grid.world_to_voxel().fixed_view::<3, 3>(0, 0).into_owned();
    let dets: Vec<f64> = voxels
        .par_iter()
        .map(|&v| {
            let n = v as usize;
            let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
            // Columns: ∂d/∂i, ∂d/∂j, ∂d/∂k.
            let mut g = Matrix3::zeros();
            for a in 0..3 {
                let lo = if ijk[a] > 0 { n - stride[a] } else { n };
                let hi = if ijk[a] + 1 < dims[a] { n + stride[a] } else { n };
                let span = ((hi - lo) / stride[a]) as f64;
                if span == 0.0 {
                    continue;
                }
                let (a0, a1) = (d(lo), d(hi));
                let col = Vector3::new(a1[0] - a0[0], a1[1] - a0[1], a1[2] - a0[2]) / span;
                g.set_column(a, &col);
            }
            (Matrix3::identity() + g * to_index).determinant()
        })
        .collect();
    Folding {
        voxels: dets.len(),
        non_positive: dets.iter().filter(|&&j| j <= 0.0).count(),
        min: dets.iter().copied().fold(1.0, f64::min),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slab_between_two_planes_gets_the_linear_stretch() {
        // Free voxels 1..=8 along i between fixed d = (4, 1, −2) at i = 0 and 0 at i = 9:
        // the discrete harmonic function of one variable is linear, d(i) = d₀ (9 − i) / 9,
        // whatever the voxel sizes (the j, k neighbours carry the same values).
        let grid = Grid::axis_aligned([10, 3, 4], [0.7, 1.3, 2.0], [0.0; 3]).unwrap();
        let free: Vec<bool> = (0..grid.len()).map(|n| (1..=8).contains(&(n % 10))).collect();
        let d0 = [4.0, 1.0, -2.0];
        let ext = harmonic_extension(
            &grid,
            &free,
            &|n| if n % 10 == 0 { d0 } else { [0.0; 3] },
            &ExtensionParams::default(),
        );
        assert_eq!(ext.voxels.len(), 8 * 12);
        for (&v, d) in ext.voxels.iter().zip(&ext.values) {
            let i = v as usize % 10;
            for c in 0..3 {
                let expect = d0[c] * (9 - i) as f64 / 9.0;
                assert!((d[c] - expect).abs() < 1e-6, "voxel {v}: {d:?}");
            }
        }
        // The map i ↦ x + d stretches monotonically: J = 1 + ∂d_x/∂x = 1 − 4/(9 × 0.7) > 0.
        let field = |n: usize| {
            ext.voxels.binary_search(&(n as u32)).map(|s| ext.values[s]).unwrap_or(if n % 10 == 0 {
                d0
            } else {
                [0.0; 3]
            })
        };
        let f = jacobian(&grid, &ext.voxels, &field);
        assert_eq!(f.non_positive, 0);
        assert!((f.min - (1.0 - 4.0 / (9.0 * 0.7))).abs() < 1e-6, "{f:?}");
    }

    #[test]
    fn a_gap_narrower_than_the_move_folds_and_is_reported() {
        // d₀ = 10 mm over a 9-voxel gap of 1 mm voxels: ∂d/∂x = −10/9 < −1, J < 0.
        let grid = Grid::axis_aligned([10, 1, 1], [1.0; 3], [0.0; 3]).unwrap();
        let free: Vec<bool> = (0..10).map(|i| (1..=8).contains(&i)).collect();
        let d = |n: usize| if n == 0 { [10.0, 0.0, 0.0] } else { [0.0; 3] };
        let ext = harmonic_extension(&grid, &free, &d, &ExtensionParams::default());
        let field =
            |n: usize| ext.voxels.binary_search(&(n as u32)).map(|s| ext.values[s]).unwrap_or(d(n));
        let f = jacobian(&grid, &ext.voxels, &field);
        assert_eq!(f.non_positive, 8);
        assert!((f.min - (1.0 - 10.0 / 9.0)).abs() < 1e-6, "{f:?}");
    }

    #[test]
    fn the_discrete_laplacian_vanishes_at_every_free_voxel_of_a_shell() {
        // A spherical shell between a ball (fixed, a rotation-like field) and the far
        // region (fixed 0) on an anisotropic grid: the residual of the weighted 7-point
        // Laplacian at every free voxel is at the solver's tolerance.
        let grid =
            Grid::axis_aligned([24, 20, 16], [1.0, 1.2, 1.5], [-11.5, -11.4, -11.25]).unwrap();
        let r = |n: usize| grid.world(idx(&grid, n)).coords.norm();
        let free: Vec<bool> = (0..grid.len()).map(|n| (5.0..10.0).contains(&r(n))).collect();
        let f = |n: usize| {
            let p = grid.world(idx(&grid, n));
            if r(n) < 5.0 { [p.y, -p.x, 0.5] } else { [0.0; 3] }
        };
        let ext = harmonic_extension(&grid, &free, &f, &ExtensionParams::default());
        let value =
            |n: usize| ext.voxels.binary_search(&(n as u32)).map(|s| ext.values[s]).unwrap_or(f(n));
        let h = grid.spacing();
        let [nx, ny, _] = grid.dims();
        let mut worst: f64 = 0.0;
        for &v in &ext.voxels {
            let n = v as usize;
            let c = value(n);
            let mut lap = [0.0; 3];
            for (a, s) in [(0, 1), (1, nx), (2, nx * ny)] {
                for q in [n - s, n + s] {
                    let vq = value(q);
                    for k in 0..3 {
                        lap[k] += (vq[k] - c[k]) / (h[a] * h[a]);
                    }
                }
            }
            worst = lap.iter().fold(worst, |m, x| m.max(x.abs()));
        }
        assert!(worst < 1e-5, "largest |Δd| {worst}");
    }

    fn idx(grid: &Grid, n: usize) -> [f64; 3] {
        let [nx, ny, _] = grid.dims();
        [(n % nx) as f64, ((n / nx) % ny) as f64, (n / (nx * ny)) as f64]
    }
}
