//! Sampling a volume at world points: trilinear for intensities, nearest voxel for labels.

use nalgebra::Point3;

use crate::{Grid, Volume};

/// Trilinear interpolation at continuous voxel indices; `None` outside the grid's voxel
/// centres (no extrapolation). A point within 1e-9 voxel of the last centre counts inside.
pub fn trilinear_at(volume: &Volume<f32>, ijk: [f64; 3]) -> Option<f32> {
    let dims = volume.grid.dims();
    if dims.iter().all(|&n| n >= 2) {
        return trilinear_3d(volume, dims, ijk);
    }
    let acc = corners(dims, ijk)?
        .iter()
        .filter(|(_, w)| *w != 0.0)
        .map(|&(n, w)| w * f64::from(volume.data[n]))
        .sum::<f64>();
    Some(acc as f32)
}

/// [`trilinear_at`] on a grid with at least two points along every axis (the warp's
/// inner loop): three nested linear interpolations.
#[inline]
fn trilinear_3d(volume: &Volume<f32>, dims: [usize; 3], ijk: [f64; 3]) -> Option<f32> {
    let (base, f) = cell(dims, ijk)?;
    let (sj, sk) = (dims[0], dims[0] * dims[1]);
    let i0 = base[0] + sj * base[1] + sk * base[2];
    let d = &volume.data[i0..i0 + sk + sj + 2];
    let lerp = |a: f32, b: f32, t: f64| f64::from(a) * (1.0 - t) + f64::from(b) * t;
    let c00 = lerp(d[0], d[1], f[0]);
    let c10 = lerp(d[sj], d[sj + 1], f[0]);
    let c01 = lerp(d[sk], d[sk + 1], f[0]);
    let c11 = lerp(d[sk + sj], d[sk + sj + 1], f[0]);
    let c0 = c00 * (1.0 - f[1]) + c10 * f[1];
    let c1 = c01 * (1.0 - f[1]) + c11 * f[1];
    Some((c0 * (1.0 - f[2]) + c1 * f[2]) as f32)
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

/// The label of the voxel nearest to world point `p` whose label is not in `excluded`
/// (sorted), looking up to `radius` voxels away along each axis (the nearest by index
/// distance, ties to the first in i-fastest order); 0 (background) when there is none,
/// or when `p` lies outside the grid.
pub fn nearest_excluding(
    volume: &Volume<u32>,
    p: &Point3<f64>,
    excluded: &[u32],
    radius: usize,
) -> u32 {
    let ijk = volume.grid.voxel(p);
    let ok = |n: usize| excluded.binary_search(&volume.data[n]).is_err();
    nearest_where(volume.grid.dims(), ijk, radius, ok).map_or(0, |n| volume.data[n])
}

/// Where a trilinear sample at world point `p` on `grid` reads the voxels flagged in
/// `allowed` only: `p` itself when every corner of its cell with a weight is allowed (or
/// when `p` lies outside the grid's voxel centres, where there is nothing to sample), else
/// the centre of the nearest allowed voxel within `radius` voxels along each axis (as
/// [`nearest_excluding`] finds it; a sample there is that voxel's value), else `p`.
/// `allowed` is indexed like the grid's voxels (i fastest).
pub fn settle_within(grid: &Grid, p: &Point3<f64>, allowed: &[bool], radius: usize) -> Point3<f64> {
    let ijk = grid.voxel(p);
    let dims = grid.dims();
    let Some(corners) = corners(dims, ijk) else { return *p };
    if corners.iter().all(|&(n, w)| w == 0.0 || allowed[n]) {
        return *p;
    }
    nearest_where(dims, ijk, radius, |n| allowed[n]).map_or(*p, |n| grid.centre(n))
}

/// The interpolation cell of continuous indices `ijk`: its lowest corner and the fractions
/// along each axis (zero along an axis of one voxel); `None` outside the voxel centres (a
/// point within 1e-9 voxel of the last centre counts inside).
#[inline]
fn cell(dims: [usize; 3], ijk: [f64; 3]) -> Option<([usize; 3], [f64; 3])> {
    let mut base = [0usize; 3];
    let mut frac = [0.0f64; 3];
    for a in 0..3 {
        let last = (dims[a] - 1) as f64;
        let x = ijk[a];
        if !(x >= -1e-9 && x <= last + 1e-9) {
            return None;
        }
        let x = x.clamp(0.0, last);
        base[a] = (x as usize).min(dims[a].saturating_sub(2));
        frac[a] = if dims[a] == 1 { 0.0 } else { x - base[a] as f64 };
    }
    Some((base, frac))
}

/// The eight trilinear corners of continuous indices `ijk` with their weights (an axis of
/// one voxel gives its upper corners weight zero); `None` outside the voxel centres.
fn corners(dims: [usize; 3], ijk: [f64; 3]) -> Option<[(usize, f64); 8]> {
    let (base, frac) = cell(dims, ijk)?;
    let step = [1usize, dims[0], dims[0] * dims[1]];
    let i0 = base[0] + step[1] * base[1] + step[2] * base[2];
    let mut out = [(i0, 0.0); 8];
    for (corner, o) in out.iter_mut().enumerate() {
        let mut w = 1.0;
        for a in 0..3 {
            if corner >> a & 1 == 1 {
                if dims[a] == 1 {
                    w = 0.0;
                } else {
                    w *= frac[a];
                    o.0 += step[a];
                }
            } else {
                w *= 1.0 - frac[a];
            }
        }
        o.1 = w;
    }
    Some(out)
}

/// The linear index of the voxel nearest to continuous indices `ijk` for which `ok` holds,
/// among those up to `radius` voxels away along each axis from the nearest centre (ties to
/// the smallest index, the first in i-fastest order); `None` when there is none or `ijk`
/// lies outside the grid. Searched in cube shells outwards, stopping once no farther shell
/// can hold a nearer voxel, so a near hit costs a few voxels whatever the radius.
fn nearest_where(
    dims: [usize; 3],
    ijk: [f64; 3],
    radius: usize,
    ok: impl Fn(usize) -> bool,
) -> Option<usize> {
    let centre = ijk.map(|x| x.round());
    if (0..3).any(|a| !(centre[a] >= 0.0 && centre[a] <= (dims[a] - 1) as f64)) {
        return None;
    }
    let c = centre.map(|x| x as isize);
    let mut best: Option<(f64, usize)> = None;
    for r in 0..=radius as isize {
        // Every voxel of shell r is at least r − 1/2 from ijk (|ijk − centre| ≤ 1/2 per axis).
        if best.is_some_and(|(d2, _)| (r as f64 - 0.5).powi(2) > d2) {
            break;
        }
        for dk in -r..=r {
            for dj in -r..=r {
                for di in -r..=r {
                    if di.abs().max(dj.abs()).max(dk.abs()) != r {
                        continue;
                    }
                    let q = [c[0] + di, c[1] + dj, c[2] + dk];
                    if (0..3).any(|a| q[a] < 0 || q[a] >= dims[a] as isize) {
                        continue;
                    }
                    let n = q[0] as usize + dims[0] * (q[1] as usize + dims[1] * q[2] as usize);
                    if !ok(n) {
                        continue;
                    }
                    let d2: f64 = (0..3).map(|a| (q[a] as f64 - ijk[a]).powi(2)).sum();
                    if best.is_none_or(|(b, m)| d2 < b || (d2 == b && n < m)) {
                        best = Some((d2, n));
                    }
                }
            }
        }
    }
    best.map(|(_, n)| n)
}

/// The labels (sorted) more than half of whose voxels are flagged in `inside`.
pub fn labels_mostly_inside(labels: &[u32], inside: &[bool]) -> Vec<u32> {
    let mut counts: std::collections::BTreeMap<u32, (usize, usize)> = Default::default();
    for (&l, &i) in labels.iter().zip(inside) {
        let e = counts.entry(l).or_default();
        e.0 += usize::from(i);
        e.1 += 1;
    }
    counts.into_iter().filter(|(_, (i, n))| 2 * i > *n).map(|(l, _)| l).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Grid;

    #[test]
    fn trilinear_is_the_product_of_three_hat_functions_and_none_beyond_the_centres() {
        // Arbitrary values on a 4 × 5 × 3 grid; the reference is the eight-corner sum of
        // hat-function products, written out here independently.
        let dims = [4usize, 5, 3];
        let grid = Grid::axis_aligned(dims, [1.0; 3], [0.0; 3]).unwrap();
        let value = |i: usize, j: usize, k: usize| ((i * 7 + j * 13 + k * 29) % 17) as f32 - 3.5;
        let data = (0..60).map(|n| value(n % 4, (n / 4) % 5, n / 20)).collect();
        let v = Volume { grid, data };
        let hat = |x: f64, c: usize| (1.0 - (x - c as f64).abs()).max(0.0);
        for p in [
            [0.0, 0.0, 0.0],
            [3.0, 4.0, 2.0],
            [1.25, 3.5, 0.75],
            [2.999, 0.001, 1.5],
            [0.5, 2.0, 2.0],
        ] {
            let mut want = 0.0;
            for k in 0..3 {
                for j in 0..5 {
                    for i in 0..4 {
                        want +=
                            f64::from(value(i, j, k)) * hat(p[0], i) * hat(p[1], j) * hat(p[2], k);
                    }
                }
            }
            let got = trilinear_at(&v, p).unwrap();
            assert!((f64::from(got) - want).abs() < 1e-5, "{p:?}: {got} vs {want}");
        }
        // Within 1e-9 of the last centre: inside; beyond it: none.
        assert!(trilinear_at(&v, [3.0 + 1e-10, 0.0, 0.0]).is_some());
        assert_eq!(trilinear_at(&v, [3.0 + 1e-6, 0.0, 0.0]), None);
        assert_eq!(trilinear_at(&v, [0.0, -1e-6, 0.0]), None);
    }

    #[test]
    fn a_point_settles_where_its_sample_reads_allowed_voxels_only() {
        // A 6 × 5 × 4 grid (spacing 2 mm, shifted origin); voxels with i ≥ 3 are not
        // allowed (think: the pre-operative brain). Expected by hand: a point whose cell has
        // a weighted corner at i ≥ 3 moves to the centre of the nearest voxel with i ≤ 2.
        let dims = [6usize, 5, 4];
        let grid = Grid::axis_aligned(dims, [2.0; 3], [-1.0, 0.5, 3.0]).unwrap();
        let allowed: Vec<bool> = (0..120).map(|n| n % 6 < 3).collect();
        let world = |p: [f64; 3]| grid.world(p);
        let close = |a: Point3<f64>, b: Point3<f64>| (a - b).norm() < 1e-9;
        // Every weighted corner allowed (i ≤ 2, or i = 2 exactly with no weight beyond):
        // the point itself.
        for p in [[0.5, 1.25, 2.0], [1.9, 3.5, 0.75], [2.0, 0.1, 2.6]] {
            assert!(close(settle_within(&grid, &world(p), &allowed, 2), world(p)), "{p:?}");
        }
        // A corner at i = 3 carries weight: the nearest allowed centre, i = 2, j and k
        // rounded.
        let got = settle_within(&grid, &world([2.4, 3.4, 0.75]), &allowed, 2);
        assert!(close(got, world([2.0, 3.0, 1.0])), "{got:?}");
        // No allowed voxel within one voxel: the nearest two voxels away.
        let got = settle_within(&grid, &world([3.6, 2.2, 1.0]), &allowed, 2);
        assert!(close(got, world([2.0, 2.0, 1.0])), "{got:?}");
        // None within the radius, or outside the grid: unchanged.
        let far = world([5.0, 2.0, 1.0]);
        assert!(close(settle_within(&grid, &far, &allowed, 2), far));
        let out = world([-0.5, 2.0, 1.0]);
        assert!(close(settle_within(&grid, &out, &allowed, 2), out));
        // A sample at the settled point is the voxel's value, as ITK's would be there.
        let data: Vec<f32> = (0..120).map(|n| (n % 13) as f32).collect();
        let v = Volume { grid: grid.clone(), data };
        let got = settle_within(&grid, &world([3.6, 2.2, 1.0]), &allowed, 2);
        let n = 2 + 6 * (2 + 5);
        assert!((trilinear(&v, &got).unwrap() - v.data[n]).abs() < 1e-5);
    }

    #[test]
    fn the_nearest_label_not_excluded_is_found_or_background() {
        // Labels 1 for i < 4, 2 for 4 ≤ i < 6, 7 beyond, on a 10 × 3 × 3 grid.
        let grid = Grid::axis_aligned([10, 3, 3], [1.0; 3], [0.0; 3]).unwrap();
        let data = (0..90)
            .map(|n| match n % 10 {
                0..=3 => 1,
                4 | 5 => 2,
                _ => 7,
            })
            .collect();
        let v = Volume { grid, data };
        let at = |x: f64| Point3::new(x, 1.0, 1.0);
        assert_eq!(nearest_excluding(&v, &at(2.2), &[], 3), 1);
        assert_eq!(nearest_excluding(&v, &at(2.2), &[1], 3), 2);
        assert_eq!(nearest_excluding(&v, &at(2.6), &[1, 2], 3), 7);
        assert_eq!(nearest_excluding(&v, &at(0.0), &[1, 2], 3), 0, "7 is 6 voxels away");
        assert_eq!(nearest_excluding(&v, &at(-3.0), &[], 3), 0, "outside the grid");
        let inside: Vec<bool> = (0..90).map(|n| n % 10 < 5).collect();
        assert_eq!(labels_mostly_inside(&v.data, &inside), vec![1]);
    }
}
