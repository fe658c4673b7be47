//! The map outside the deformed brain: where the brain moved away from the skull (or
//! towards it), a voxel must sample what was there before — fluid between the old brain
//! surface and the skull — not the old cortex. The displacement field d(y) = X(y) − y is
//! extended harmonically from the brain to the skull on the image's own grid
//! (`bs_image::extend`):
//!
//! * Dirichlet data: inside the deformed brain, the exact inverse of the finite-element map
//!   (unchanged); outside the skull cavity, zero (the skull is rigid, bone and scalp do not
//!   move). The skull cavity is the inside of the closed skull surface rasterised on the
//!   grid (`bs_mesh::lattice_inside`).
//! * The skin: a gap voxel with a face neighbour inside the deformed brain holds the
//!   finite-element inverse continued linearly across the surface (that neighbour's
//!   tetrahedron's affine map), so that the field interpolated across the brain surface
//!   (as ITK does) is the finite-element map's to second order: at the demo's 50 most
//!   displaced nodes field(X + u) is −u within 0.08 mm (0.63 mm with the harmonic
//!   extension starting at the brain's voxels, 6.5 mm with zero outside the brain).
//! * Unknowns: the other voxels inside the cavity and outside the deformed brain (the gap).
//! * A scene without a skull: the gap is a band around the deformed brain, [`band_width`]
//!   wide (twice the largest displacement, at least [`MIN_BAND_MM`]), beyond which d = 0:
//!   the extension decays to zero over that distance.
//!
//! Why the grid and not a mesh of the gap: the grid is where both outputs live (the warp
//! samples at y + d(y), the field *is* d on the grid), it needs no second mesher conforming
//! to an arbitrary brain surface and skull, and the gap between the brain's voxels and the
//! skull's is solved in tens of milliseconds.
//!
//! In one dimension the harmonic extension is the linear stretch of the new gap onto the old
//! one, monotone while the old gap has width (dX/dy = gap_old / gap_new > 0). Where contact
//! closes the gap there are no gap voxels: d jumps from the brain's (frictionless, sliding)
//! displacement to zero at the rigid skull, within a voxel. Where a brain that touched the
//! skull moves away, the old gap had zero width: the vacated voxels all sample the old
//! surface layer (det(I + ∇d) → 0). [`Folding`] reports det(I + ∇d) on the gap voxels: the
//! count of voxels where it is ≤ 0 (the map folds) and its minimum. The warp therefore
//! samples a gap voxel beyond the skin from the voxels of the pre-operative gap only
//! (`InverseMap::warp`); the map, and the exported field, stay as they are.

use bs_image::Grid;
use bs_image::extend::{ExtensionParams, Folding, harmonic_extension, indices_where, jacobian};
use rayon::prelude::*;
use std::sync::OnceLock;

/// The narrowest band of a skull-free extension (mm).
pub const MIN_BAND_MM: f64 = 10.0;

/// The width of a skull-free extension's band for a largest displacement `max_u` (mm):
/// 2 |u|max, at least [`MIN_BAND_MM`], so that in one dimension d falls by at most half a
/// millimetre per millimetre and the map stays monotone.
pub fn band_width(max_u: f64) -> f64 {
    (2.0 * max_u).max(MIN_BAND_MM)
}

/// The gap voxels (`gap`, ascending) the deformed brain (`in_brain`) encloses: those not
/// connected through face neighbours in the gap to a voxel outside both (beyond the skull
/// or the band) or to the grid's border. After a resection they are its cavity.
pub fn enclosed(grid: &Grid, gap: &[u32], in_brain: &[bool]) -> Vec<u32> {
    let [nx, ny, nz] = grid.dims();
    let mut is_gap = vec![false; nx * ny * nz];
    gap.iter().for_each(|&n| is_gap[n as usize] = true);
    let neighbours = |n: usize| {
        let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
        [
            (i > 0).then(|| n - 1),
            (i + 1 < nx).then(|| n + 1),
            (j > 0).then(|| n - nx),
            (j + 1 < ny).then(|| n + nx),
            (k > 0).then(|| n - nx * ny),
            (k + 1 < nz).then(|| n + nx * ny),
        ]
    };
    // Seeds: gap voxels on the border or beside a voxel that is neither gap nor brain.
    let mut reached = vec![false; nx * ny * nz];
    let mut queue: Vec<usize> = gap
        .iter()
        .map(|&n| n as usize)
        .filter(|&n| neighbours(n).iter().any(|q| q.is_none_or(|q| !is_gap[q] && !in_brain[q])))
        .collect();
    queue.iter().for_each(|&n| reached[n] = true);
    while let Some(n) = queue.pop() {
        for q in neighbours(n).into_iter().flatten() {
            if is_gap[q] && !reached[q] {
                reached[q] = true;
                queue.push(q);
            }
        }
    }
    gap.iter().copied().filter(|&n| !reached[n as usize]).collect()
}

/// Where the extension stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Boundary {
    /// At the skull cavity's surface (d = 0 outside it).
    Skull,
    /// At this distance (mm) from the deformed brain (no skull in the scene).
    Band(f64),
}

/// What the extension did, for the front ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutsideReport {
    /// Where it stops.
    pub boundary: Boundary,
    /// Voxels solved for (inside the cavity or band, outside the deformed brain).
    pub gap_voxels: usize,
    /// Conjugate-gradient iterations.
    pub iterations: usize,
    /// Relative residual reached.
    pub residual: f64,
    /// det(I + ∇d) on the gap voxels.
    pub folding: Folding,
    /// Where det(I + ∇d) is smallest (the image's world frame, mm).
    pub worst_at: Option<[f64; 3]>,
}

/// The extended field on the gap voxels.
#[derive(Debug, Clone)]
pub struct Outside {
    /// Gap voxels, ascending linear indices.
    pub voxels: Vec<u32>,
    /// d(y) there (image frame, mm).
    pub values: Vec<[f64; 3]>,
    /// Whether each gap voxel is on the skin (a face neighbour inside the deformed brain,
    /// d the finite-element inverse continued across the surface).
    pub skin: Vec<bool>,
    /// Per grid voxel: its place in `voxels` + 1, zero off the gap (only the pages that
    /// hold gap voxels are ever written).
    slot: Vec<u32>,
    boundary: Boundary,
    iterations: usize,
    residual: f64,
    /// det(I + ∇d) on the gap voxels and where it is smallest, measured on first ask.
    folding: OnceLock<(Folding, Option<[f64; 3]>)>,
}

impl Outside {
    /// The extended d at voxel `n` if it is a gap voxel.
    pub fn get(&self, n: usize) -> Option<[f64; 3]> {
        match self.slot.get(n).copied().unwrap_or(0) {
            0 => None,
            s => Some(self.values[s as usize - 1]),
        }
    }

    /// What the extension did. Whether the map folds is measured on the first call, not
    /// when the map is built (13 ms on the 8.7 M-voxel MNI152 grid): a live session's
    /// server sends the warped image first and its report last. `inside(n)`: d at a voxel
    /// inside the deformed brain (the exact inverse), `None` elsewhere.
    pub fn report(
        &self,
        grid: &Grid,
        inside: impl Fn(usize) -> Option<[f64; 3]> + Sync,
    ) -> OutsideReport {
        let (folding, worst_at) = *self.folding.get_or_init(|| {
            let field = |n: usize| self.get(n).or_else(|| inside(n)).unwrap_or([0.0; 3]);
            let folding = jacobian(grid, &self.voxels, &field);
            let at = folding.worst.map(|v| {
                let p = grid.centre(v as usize);
                [p.x, p.y, p.z]
            });
            (folding, at)
        });
        OutsideReport {
            boundary: self.boundary,
            gap_voxels: self.voxels.len(),
            iterations: self.iterations,
            residual: self.residual,
            folding,
            worst_at,
        }
    }
}

/// Extends `exact` (d on the voxels where `in_brain` is true) into the gap. `cavity`: the
/// voxels inside the skull (None: no skull, a band of [`band_width`]`(max_u)` instead).
/// `skin(n)`: d at a gap voxel that touches the brain (a face neighbour inside it), the
/// finite-element inverse continued across the surface; these voxels hold it, so that the
/// field interpolated between them and the brain's voxels (as ITK does) stays the
/// finite-element map's to second order at the brain surface, and the harmonic extension
/// starts beyond them.
pub fn extend(
    grid: &Grid,
    in_brain: &[bool],
    cavity: Option<&[bool]>,
    max_u: f64,
    exact: impl Fn(usize) -> [f64; 3] + Sync,
    skin: impl Fn(usize) -> Option<[f64; 3]> + Sync,
) -> Outside {
    let (mut free, boundary): (Vec<bool>, Boundary) = match cavity {
        Some(c) => (c.par_iter().zip(in_brain).map(|(&c, &b)| c && !b).collect(), Boundary::Skull),
        None => {
            let width = band_width(max_u);
            let d2 = bs_meshgen::edt::squared_distance(in_brain, grid.dims(), grid.spacing());
            let w2 = (width * width) as f32;
            let free = d2.par_iter().zip(in_brain).map(|(&d, &b)| !b && d <= w2).collect();
            (free, Boundary::Band(width))
        }
    };
    // The skin: gap voxels with the brain on a face; fixed at the continued FE inverse.
    let candidates = indices_where(&free);
    let skin_values: Vec<(u32, [f64; 3])> =
        candidates.par_iter().filter_map(|&n| skin(n as usize).map(|d| (n, d))).collect();
    drop(candidates);
    // Voxel → its place in a list + 1 (zero elsewhere: only pages with gap voxels are written).
    let mut slot = vec![0u32; grid.len()];
    for (s, &(v, _)) in skin_values.iter().enumerate() {
        free[v as usize] = false;
        slot[v as usize] = s as u32 + 1;
    }
    let value = |n: usize| {
        if in_brain[n] {
            exact(n)
        } else if slot[n] != 0 {
            skin_values[slot[n] as usize - 1].1
        } else {
            [0.0; 3]
        }
    };
    let ext = harmonic_extension(grid, &free, &value, &ExtensionParams::default());
    drop(free);
    // The gap: the skin and the harmonic voxels together, ascending (a merge of two sorted
    // lists); the skin's table becomes the gap's.
    let (voxels, values) = merge(&skin_values, &ext.voxels, &ext.values);
    let mut skin = vec![false; voxels.len()];
    for &(v, _) in &skin_values {
        if let Ok(i) = voxels.binary_search(&v) {
            skin[i] = true;
        }
    }
    for (s, &v) in voxels.iter().enumerate() {
        slot[v as usize] = s as u32 + 1;
    }
    Outside {
        voxels,
        values,
        skin,
        slot,
        boundary,
        iterations: ext.iterations,
        residual: ext.residual,
        folding: OnceLock::new(),
    }
}

/// The union of two lists of voxels with their values, each ascending and disjoint, as one
/// ascending list.
fn merge(a: &[(u32, [f64; 3])], voxels: &[u32], values: &[[f64; 3]]) -> (Vec<u32>, Vec<[f64; 3]>) {
    let n = a.len() + voxels.len();
    let (mut out_v, mut out_d) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < voxels.len() {
        if j == voxels.len() || (i < a.len() && a[i].0 < voxels[j]) {
            out_v.push(a[i].0);
            out_d.push(a[i].1);
            i += 1;
        } else {
            out_v.push(voxels[j]);
            out_d.push(values[j]);
            j += 1;
        }
    }
    (out_v, out_d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_gap_the_brain_encloses_is_enclosed() {
        // A 9³ grid: a brain shell (voxels 2..=6 on every axis) around a hole (4, 4, 4), gap
        // voxels the hole and the layer just outside the shell (1 and 7 on some axis).
        let g = Grid::axis_aligned([9, 9, 9], [1.0; 3], [0.0; 3]).unwrap();
        let ijk = |n: usize| [n % 9, (n / 9) % 9, n / 81];
        let within =
            |v: [usize; 3], lo: usize, hi: usize| v.iter().all(|&c| (lo..=hi).contains(&c));
        let hole = g.index(4, 4, 4);
        let in_brain: Vec<bool> = (0..g.len()).map(|n| within(ijk(n), 2, 6) && n != hole).collect();
        let gap: Vec<u32> = (0..g.len())
            .filter(|&n| n == hole || (within(ijk(n), 1, 7) && !within(ijk(n), 2, 6)))
            .map(|n| n as u32)
            .collect();
        assert_eq!(enclosed(&g, &gap, &in_brain), vec![hole as u32]);
        // Open the shell at one voxel: the hole joins the outer gap.
        let mut open = in_brain.clone();
        open[g.index(4, 4, 5)] = false;
        open[g.index(4, 4, 6)] = false;
        let mut gap_open = gap.clone();
        gap_open.extend([g.index(4, 4, 5) as u32, g.index(4, 4, 6) as u32]);
        gap_open.sort_unstable();
        assert!(enclosed(&g, &gap_open, &open).is_empty());
    }

    #[test]
    fn merge_interleaves_two_ascending_lists_with_their_values() {
        let skin = [(2u32, [2.0; 3]), (5, [5.0; 3]), (9, [9.0; 3])];
        let voxels = [0u32, 3, 4, 10, 11];
        let values: Vec<[f64; 3]> = voxels.iter().map(|&v| [f64::from(v); 3]).collect();
        let (v, d) = merge(&skin, &voxels, &values);
        assert_eq!(v, [0, 2, 3, 4, 5, 9, 10, 11]);
        assert!(v.iter().zip(&d).all(|(&v, d)| *d == [f64::from(v); 3]));
        assert_eq!(merge(&[], &voxels, &values).0, voxels);
        assert_eq!(merge(&skin, &[], &[]).0, [2, 5, 9]);
    }
}
