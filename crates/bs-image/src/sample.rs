//! Sampling a volume at world points: trilinear for intensities, nearest voxel for labels.

use nalgebra::Point3;

use crate::Volume;

/// Trilinear interpolation at continuous voxel indices; `None` outside the grid's voxel
/// centres (no extrapolation). A point within 1e-9 voxel of the last centre counts inside.
pub fn trilinear_at(volume: &Volume<f32>, ijk: [f64; 3]) -> Option<f32> {
    let dims = volume.grid.dims();
    let mut base = [0usize; 3];
    let mut frac = [0.0f64; 3];
    for a in 0..3 {
        let x = ijk[a];
        let last = (dims[a] - 1) as f64;
        if !(x >= -1e-9 && x <= last + 1e-9) {
            return None;
        }
        let x = x.clamp(0.0, last);
        let b = (x.floor() as usize).min(dims[a].saturating_sub(2));
        base[a] = b;
        frac[a] = if dims[a] == 1 { 0.0 } else { x - b as f64 };
    }
    let g = &volume.grid;
    let step = [1usize, dims[0], dims[0] * dims[1]];
    let i0 = g.index(base[0], base[1], base[2]);
    let mut acc = 0.0f64;
    for corner in 0..8usize {
        let mut w = 1.0;
        let mut idx = i0;
        for a in 0..3 {
            if corner >> a & 1 == 1 {
                if dims[a] == 1 {
                    w = 0.0;
                } else {
                    w *= frac[a];
                    idx += step[a];
                }
            } else {
                w *= 1.0 - frac[a];
            }
        }
        if w != 0.0 {
            acc += w * volume.data[idx] as f64;
        }
    }
    Some(acc as f32)
}

/// Trilinear interpolation at a world point.
pub fn trilinear(volume: &Volume<f32>, p: &Point3<f64>) -> Option<f32> {
    trilinear_at(volume, volume.grid.voxel(p))
}

/// The value of the voxel whose centre is nearest to continuous indices `ijk`; `None`
/// outside the grid (more than half a voxel beyond the outer centres).
pub fn nearest_at<T: Copy>(volume: &Volume<T>, ijk: [f64; 3]) -> Option<T> {
    let dims = volume.grid.dims();
    let mut idx = [0usize; 3];
    for a in 0..3 {
        let r = ijk[a].round();
        if !(r >= 0.0 && r <= (dims[a] - 1) as f64) {
            return None;
        }
        idx[a] = r as usize;
    }
    Some(volume.at(idx[0], idx[1], idx[2]))
}

/// Nearest-voxel value at a world point.
pub fn nearest<T: Copy>(volume: &Volume<T>, p: &Point3<f64>) -> Option<T> {
    nearest_at(volume, volume.grid.voxel(p))
}
