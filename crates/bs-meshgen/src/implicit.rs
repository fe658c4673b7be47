//! Implicit functions from a labelmap: indicator images on a padded working grid,
//! separable Gaussian smoothing, and trilinear evaluation at world points.
//!
//! A smoothed indicator `φ = G_σ * 1[label ∈ set]` is continuous, so its level set
//! `φ = 1/2` is a smooth surface through the voxel faces of the segmentation instead of a
//! staircase; the meshers use `f = 1/2 − φ` (negative inside).

use bs_image::{Grid, Volume};
use nalgebra::{Matrix4, Point3, Vector3};
use rayon::prelude::*;

/// A working grid: a box of voxels of the source image, possibly extending beyond it
/// (voxels outside the image are background), with the source's voxel-to-world map.
#[derive(Debug, Clone)]
pub struct WorkGrid {
    /// The grid (its voxel (0,0,0) is source voxel `offset`).
    pub grid: Grid,
    /// Source voxel index of this grid's voxel (0, 0, 0).
    pub offset: [i64; 3],
}

impl WorkGrid {
    /// The voxels `lo..=hi` of `source` (indices may lie outside the source image).
    pub fn new(source: &Grid, lo: [i64; 3], hi: [i64; 3]) -> WorkGrid {
        let dims = [0, 1, 2].map(|a| (hi[a] - lo[a] + 1).max(1) as usize);
        let shift =
            Matrix4::new_translation(&Vector3::new(lo[0] as f64, lo[1] as f64, lo[2] as f64));
        let affine = source.voxel_to_world() * shift;
        // The source affine is valid, so the shifted one is too.
        let grid = Grid::new(dims, affine).expect("a translated valid affine stays valid");
        WorkGrid { grid, offset: lo }
    }

    /// Number of voxels along each axis.
    pub fn dims(&self) -> [usize; 3] {
        self.grid.dims()
    }

    /// A 0/1 indicator (as f32) of the source voxels for which `inside(label)` holds.
    pub fn indicator(&self, labels: &Volume<u32>, inside: impl Fn(u32) -> bool + Sync) -> Vec<f32> {
        let [nx, ny, nz] = self.dims();
        let src = labels.grid.dims();
        let mut out = vec![0f32; nx * ny * nz];
        out.par_chunks_mut(nx).enumerate().for_each(|(row, line)| {
            let (j, k) = (row % ny, row / ny);
            let sj = j as i64 + self.offset[1];
            let sk = k as i64 + self.offset[2];
            if sj < 0 || sk < 0 || sj >= src[1] as i64 || sk >= src[2] as i64 {
                return;
            }
            let base = labels.grid.index(0, sj as usize, sk as usize);
            for (i, v) in line.iter_mut().enumerate() {
                let si = i as i64 + self.offset[0];
                if si >= 0 && si < src[0] as i64 && inside(labels.data[base + si as usize]) {
                    *v = 1.0;
                }
            }
        });
        out
    }
}

/// Block means of `data` on `grid` over `f`×`f`×`f` voxel blocks, with the grid of the
/// block centres (partial blocks at the far faces average the voxels they have).
pub fn coarsen(grid: &Grid, data: &[f32], f: usize) -> (Grid, Vec<f32>) {
    let [nx, ny, nz] = grid.dims();
    let dims = [nx, ny, nz].map(|n| n.div_ceil(f));
    let c = (f as f64 - 1.0) / 2.0;
    let mut m = Matrix4::identity() * f as f64;
    m[(3, 3)] = 1.0;
    for a in 0..3 {
        m[(a, 3)] = c;
    }
    let coarse =
        Grid::new(dims, grid.voxel_to_world() * m).expect("a scaled valid affine stays valid");
    let [cx, cy, _] = dims;
    let mut out = vec![0f32; dims[0] * dims[1] * dims[2]];
    out.par_chunks_mut(cx * cy).enumerate().for_each(|(kk, slab)| {
        for jj in 0..cy {
            for ii in 0..cx {
                let (mut s, mut n) = (0f32, 0u32);
                for k in kk * f..((kk + 1) * f).min(nz) {
                    for j in jj * f..((jj + 1) * f).min(ny) {
                        let row = nx * (j + ny * k);
                        for i in ii * f..((ii + 1) * f).min(nx) {
                            s += data[row + i];
                            n += 1;
                        }
                    }
                }
                slab[ii + cx * jj] = s / n as f32;
            }
        }
    });
    (coarse, out)
}

/// Smallest box of voxels (inclusive) whose label satisfies `pred`, or `None`.
pub fn bounding_box(
    labels: &Volume<u32>,
    pred: impl Fn(u32) -> bool + Sync,
) -> Option<([i64; 3], [i64; 3])> {
    let [nx, ny, _] = labels.grid.dims();
    labels
        .data
        .par_chunks(nx)
        .enumerate()
        .filter_map(|(row, line)| {
            let first = line.iter().position(|&l| pred(l))?;
            let last = line.iter().rposition(|&l| pred(l))?;
            let (j, k) = ((row % ny) as i64, (row / ny) as i64);
            Some(([first as i64, j, k], [last as i64, j, k]))
        })
        .reduce_with(|(alo, ahi), (blo, bhi)| {
            ([0, 1, 2].map(|a| alo[a].min(blo[a])), [0, 1, 2].map(|a| ahi[a].max(bhi[a])))
        })
}

/// A scalar field sampled on a working grid, evaluated by trilinear interpolation at world
/// points; points outside the grid take the value `outside`.
#[derive(Debug, Clone)]
pub struct SampledField {
    /// The grid the samples live on.
    pub grid: Grid,
    /// One value per voxel, first index fastest.
    pub data: Vec<f32>,
    /// Value outside the grid.
    pub outside: f32,
    /// Value subtracted from the interpolated sample (the level of the surface).
    pub level: f32,
}

impl SampledField {
    /// `sign · (sample(p) − level)`-style evaluation: returns `level − sample(p)`, negative
    /// where the sample exceeds the level (inside an indicator's region).
    #[inline]
    pub fn eval(&self, p: &Point3<f64>) -> f64 {
        f64::from(self.level) - self.sample(p)
    }

    /// The trilinearly interpolated sample at world point `p`.
    #[inline]
    pub fn sample(&self, p: &Point3<f64>) -> f64 {
        let v = self.grid.world_to_voxel().transform_point(p);
        let [nx, ny, nz] = self.grid.dims();
        let c = [v.x, v.y, v.z];
        let mut i0 = [0usize; 3];
        let mut t = [0f64; 3];
        for a in 0..3 {
            let n = [nx, ny, nz][a];
            if !(c[a] >= 0.0 && c[a] <= (n - 1) as f64) {
                return f64::from(self.outside);
            }
            let fl = c[a].floor();
            let mut i = fl as usize;
            let mut frac = c[a] - fl;
            if i + 1 >= n {
                // On the last sample (or a single-voxel axis): no right neighbour.
                i = n.saturating_sub(2);
                frac = if n == 1 { 0.0 } else { c[a] - i as f64 };
            }
            i0[a] = i;
            t[a] = frac;
        }
        let sx = 1;
        let sy = nx;
        let sz = nx * ny;
        let base = i0[0] + nx * (i0[1] + ny * i0[2]);
        let dx = if nx > 1 { sx } else { 0 };
        let dy = if ny > 1 { sy } else { 0 };
        let dz = if nz > 1 { sz } else { 0 };
        let d = &self.data;
        let g = |o: usize| f64::from(d[base + o]);
        let c00 = g(0) * (1.0 - t[0]) + g(dx) * t[0];
        let c10 = g(dy) * (1.0 - t[0]) + g(dy + dx) * t[0];
        let c01 = g(dz) * (1.0 - t[0]) + g(dz + dx) * t[0];
        let c11 = g(dz + dy) * (1.0 - t[0]) + g(dz + dy + dx) * t[0];
        let c0 = c00 * (1.0 - t[1]) + c10 * t[1];
        let c1 = c01 * (1.0 - t[1]) + c11 * t[1];
        c0 * (1.0 - t[2]) + c1 * t[2]
    }

    /// World-space axis-aligned bounding box of the grid's voxel centres.
    pub fn world_box(&self) -> (Point3<f64>, Point3<f64>) {
        world_box(&self.grid)
    }
}

/// World-space axis-aligned bounding box of a grid's voxel centres.
pub fn world_box(grid: &Grid) -> (Point3<f64>, Point3<f64>) {
    let [nx, ny, nz] = grid.dims();
    let mut lo = Point3::from([f64::INFINITY; 3]);
    let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
    for c in 0..8 {
        let ijk = [
            if c & 1 == 0 { 0.0 } else { (nx - 1) as f64 },
            if c & 2 == 0 { 0.0 } else { (ny - 1) as f64 },
            if c & 4 == 0 { 0.0 } else { (nz - 1) as f64 },
        ];
        let p = grid.world(ijk);
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    (lo, hi)
}

/// Normalised 1-D Gaussian taps for standard deviation `sigma` (in samples), radius
/// ⌈3σ⌉; a single tap for σ ≈ 0.
fn kernel(sigma: f64) -> Vec<f32> {
    if sigma < 1e-3 {
        return vec![1.0];
    }
    let r = (3.0 * sigma).ceil() as i64;
    let w: Vec<f64> = (-r..=r).map(|x| (-(x * x) as f64 / (2.0 * sigma * sigma)).exp()).collect();
    let s: f64 = w.iter().sum();
    w.into_iter().map(|x| (x / s) as f32).collect()
}

/// Separable Gaussian smoothing in place, standard deviation `sigma[a]` voxels along axis
/// `a`; samples beyond the grid repeat the edge value. One scratch buffer for the whole
/// image, three passes (x rows, y within z-slabs, z between slabs), parallel over rows or
/// slabs.
pub fn gaussian_blur(data: &mut Vec<f32>, dims: [usize; 3], sigma: [f64; 3]) {
    let [nx, ny, nz] = dims;
    let slab = nx * ny;
    let mut tmp = vec![0f32; data.len()];
    // x: along rows.
    let k = kernel(sigma[0]);
    if k.len() > 1 {
        let r = (k.len() / 2) as i64;
        tmp.par_chunks_mut(nx).zip(data.par_chunks(nx)).for_each(|(out, inp)| {
            for (i, o) in out.iter_mut().enumerate() {
                let mut s = 0f32;
                for (t, w) in k.iter().enumerate() {
                    let j = (i as i64 + t as i64 - r).clamp(0, nx as i64 - 1) as usize;
                    s += w * inp[j];
                }
                *o = s;
            }
        });
        std::mem::swap(data, &mut tmp);
    }
    // y: rows of a slab combined with weights.
    let k = kernel(sigma[1]);
    if k.len() > 1 {
        let r = (k.len() / 2) as i64;
        tmp.par_chunks_mut(slab).zip(data.par_chunks(slab)).for_each(|(out, inp)| {
            for j in 0..ny {
                let o = &mut out[j * nx..(j + 1) * nx];
                o.fill(0.0);
                for (t, w) in k.iter().enumerate() {
                    let jj = (j as i64 + t as i64 - r).clamp(0, ny as i64 - 1) as usize;
                    for (a, b) in o.iter_mut().zip(&inp[jj * nx..(jj + 1) * nx]) {
                        *a += w * b;
                    }
                }
            }
        });
        std::mem::swap(data, &mut tmp);
    }
    // z: slabs combined with weights.
    let k = kernel(sigma[2]);
    if k.len() > 1 {
        let r = (k.len() / 2) as i64;
        let inp = &*data;
        tmp.par_chunks_mut(slab).enumerate().for_each(|(z, out)| {
            out.fill(0.0);
            for (t, w) in k.iter().enumerate() {
                let zz = (z as i64 + t as i64 - r).clamp(0, nz as i64 - 1) as usize;
                for (a, b) in out.iter_mut().zip(&inp[zz * slab..(zz + 1) * slab]) {
                    *a += w * b;
                }
            }
        });
        std::mem::swap(data, &mut tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blur_preserves_a_constant_and_the_mass_of_an_impulse() {
        let dims = [9, 7, 11];
        let mut c = vec![2.0f32; 9 * 7 * 11];
        gaussian_blur(&mut c, dims, [1.0, 0.7, 1.3]);
        assert!(c.iter().all(|v| (v - 2.0).abs() < 1e-5));
        let mut d = vec![0f32; 31 * 31 * 31];
        d[15 + 31 * (15 + 31 * 15)] = 1.0;
        gaussian_blur(&mut d, [31; 3], [1.5, 1.5, 1.5]);
        let sum: f32 = d.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "{sum}");
    }

    #[test]
    fn trilinear_sample_reproduces_a_linear_function_under_an_oblique_affine() {
        let mut m = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.9).to_homogeneous();
        m *= Matrix4::new_nonuniform_scaling(&Vector3::new(1.0, 1.5, 0.8));
        m[(0, 3)] = 10.0;
        let grid = Grid::new([6, 5, 4], m).unwrap();
        let g = grid.clone();
        let f = |i: f64, j: f64, k: f64| 1.0 + 2.0 * i - 0.5 * j + 0.25 * k;
        let mut data = vec![0f32; 120];
        for k in 0..4 {
            for j in 0..5 {
                for i in 0..6 {
                    data[g.index(i, j, k)] = f(i as f64, j as f64, k as f64) as f32;
                }
            }
        }
        let field = SampledField { grid, data, outside: -7.0, level: 0.0 };
        let p = g.world([2.3, 3.7, 1.2]);
        assert!((field.sample(&p) - f(2.3, 3.7, 1.2)).abs() < 1e-5);
        assert_eq!(field.sample(&g.world([-0.1, 1.0, 1.0])), -7.0);
    }
}
