//! Whether an extended map folds: det(I + ∇d) by central differences on a set of voxels.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::Grid;

/// How much a map y ↦ y + d(y) folds on a set of voxels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Folding {
    /// Voxels measured.
    pub voxels: usize,
    /// Voxels where det(I + ∇d) ≤ 0.
    pub non_positive: usize,
    /// Smallest det(I + ∇d) (1 when no voxel was measured).
    pub min: f64,
    /// The voxel where it is smallest (linear index), if any was measured.
    pub worst: Option<u32>,
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
    let worst = dets.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).map(|(i, _)| voxels[i]);
    Folding {
        voxels: dets.len(),
        non_positive: dets.iter().filter(|&&j| j <= 0.0).count(),
        min: dets.iter().copied().fold(1.0, f64::min),
        worst,
    }
}
