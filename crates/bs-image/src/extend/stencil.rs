//! The weighted 7-point Laplacian on the free voxels: each free voxel's free neighbours (as
//! unknowns), its diagonal, and the right-hand side its fixed neighbours contribute.

use rayon::prelude::*;

use crate::Grid;

/// No free neighbour on this side (fixed or off the grid).
pub(super) const NONE: u32 = u32::MAX;

/// `A` of `A d = b` on the free voxels, in double and single precision.
pub(super) struct Stencil {
    /// Per unknown: the unknowns of its six neighbours (−i, +i, −j, +j, −k, +k).
    pub nb: Vec<[u32; 6]>,
    pub diag: Vec<f64>,
    /// Axis weights 1/h².
    pub w: [f64; 3],
    pub diag32: Vec<f32>,
    pub w32: [f32; 3],
}

impl Stencil {
    /// The stencil of the unknowns `voxels` (ascending linear indices of the voxels where
    /// `free` holds) and the right-hand side from the fixed neighbours' values `fixed(n)`.
    pub(super) fn new(
        grid: &Grid,
        free: &[bool],
        voxels: &[u32],
        fixed: &(dyn Fn(usize) -> [f64; 3] + Sync),
    ) -> (Stencil, Vec<[f64; 3]>) {
        let [nx, ny, nz] = grid.dims();
        let h = grid.spacing();
        let w = [1.0 / (h[0] * h[0]), 1.0 / (h[1] * h[1]), 1.0 / (h[2] * h[2])];
        let stride = [1isize, nx as isize, (nx * ny) as isize];
        // Free voxel → its unknown + 1 (a dense table: one random read per neighbour; zero
        // elsewhere, so that only the pages holding free voxels are ever written).
        let mut slots = vec![0u32; grid.len()];
        for (s, &v) in voxels.iter().enumerate() {
            slots[v as usize] = s as u32 + 1;
        }
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
                            nb[2 * a + s] = slots[q].wrapping_sub(1);
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
        let nb: Vec<[u32; 6]> = setup.iter().map(|s| s.0).collect();
        let diag: Vec<f64> = setup.iter().map(|s| s.1).collect();
        let b: Vec<[f64; 3]> = setup.iter().map(|s| s.2).collect();
        let diag32 = diag.iter().map(|&d| d as f32).collect();
        let w32 = w.map(|x| x as f32);
        (Stencil { nb, diag, w, diag32, w32 }, b)
    }

    /// `(A x)_i` in double precision.
    pub(super) fn row(&self, i: usize, x: &[[f64; 3]]) -> [f64; 3] {
        row_of(&self.nb[i], self.diag[i], self.w, x, i)
    }

    /// `(A x)_i` in single precision.
    pub(super) fn row32(&self, i: usize, x: &[[f32; 3]]) -> [f32; 3] {
        row_of(&self.nb[i], self.diag32[i], self.w32, x, i)
    }

    /// Unknowns.
    pub(super) fn len(&self) -> usize {
        self.nb.len()
    }
}

/// `d x_i − Σ w x_neighbour` over the free neighbours `nb` of unknown `i`.
#[inline(always)]
fn row_of<T>(nb: &[u32; 6], d: T, w: [T; 3], x: &[[T; 3]], i: usize) -> [T; 3]
where
    T: Copy + std::ops::Mul<Output = T> + std::ops::SubAssign,
{
    let xi = &x[i];
    let mut acc = [d * xi[0], d * xi[1], d * xi[2]];
    for (a, &q) in nb.iter().enumerate() {
        if q != NONE {
            let (wq, xq) = (w[a / 2], &x[q as usize]);
            for c in 0..3 {
                acc[c] -= wq * xq[c];
            }
        }
    }
    acc
}
