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
//! count of voxels where it is ≤ 0 (the map folds) and its minimum.

use bs_image::Grid;
use bs_image::extend::{ExtensionParams, Folding, harmonic_extension, jacobian};

/// The narrowest band of a skull-free extension (mm).
pub const MIN_BAND_MM: f64 = 10.0;

/// The width of a skull-free extension's band for a largest displacement `max_u` (mm):
/// 2 |u|max, at least [`MIN_BAND_MM`], so that in one dimension d falls by at most half a
/// millimetre per millimetre and the map stays monotone.
pub fn band_width(max_u: f64) -> f64 {
    (2.0 * max_u).max(MIN_BAND_MM)
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
    /// What was done.
    pub report: OutsideReport,
}

impl Outside {
    /// The extended d at voxel `n` if it is a gap voxel.
    pub fn get(&self, n: usize) -> Option<[f64; 3]> {
        self.voxels.binary_search(&(n as u32)).ok().map(|s| self.values[s])
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
    let (free, boundary): (Vec<bool>, Boundary) = match cavity {
        Some(c) => (c.iter().zip(in_brain).map(|(&c, &b)| c && !b).collect(), Boundary::Skull),
        None => {
            let width = band_width(max_u);
            let d2 = bs_meshgen::edt::squared_distance(in_brain, grid.dims(), grid.spacing());
            let w2 = (width * width) as f32;
            (d2.iter().zip(in_brain).map(|(&d, &b)| !b && d <= w2).collect(), Boundary::Band(width))
        }
    };
    // The skin: gap voxels with the brain on a face; fixed at the continued FE inverse.
    let mut free = free;
    let skin_values: Vec<(u32, [f64; 3])> = (0..grid.len())
        .filter(|&n| free[n])
        .filter_map(|n| skin(n).map(|d| (n as u32, d)))
        .collect();
    let mut skin_slot = vec![u32::MAX; grid.len()];
    for (s, &(v, _)) in skin_values.iter().enumerate() {
        free[v as usize] = false;
        skin_slot[v as usize] = s as u32;
    }
    let value = |n: usize| {
        if in_brain[n] {
            exact(n)
        } else if skin_slot[n] != u32::MAX {
            skin_values[skin_slot[n] as usize].1
        } else {
            [0.0; 3]
        }
    };
    let ext = harmonic_extension(grid, &free, &value, &ExtensionParams::default());
    // The gap: the skin and the harmonic voxels together, ascending.
    let mut gap: Vec<(u32, [f64; 3])> = skin_values.clone();
    gap.extend(ext.voxels.iter().copied().zip(ext.values.iter().copied()));
    gap.sort_unstable_by_key(|g| g.0);
    let (voxels, values): (Vec<u32>, Vec<[f64; 3]>) = gap.into_iter().unzip();
    let mut slot = vec![u32::MAX; grid.len()];
    for (s, &v) in voxels.iter().enumerate() {
        slot[v as usize] = s as u32;
    }
    let field = |n: usize| match slot[n] {
        u32::MAX => value(n),
        s => values[s as usize],
    };
    let folding = jacobian(grid, &voxels, &field);
    let report = OutsideReport {
        boundary,
        gap_voxels: voxels.len(),
        iterations: ext.iterations,
        residual: ext.residual,
        folding,
        worst_at: folding.worst.map(|v| {
            let [nx, ny, _] = grid.dims();
            let n = v as usize;
            let p = grid.world([(n % nx) as f64, ((n / nx) % ny) as f64, (n / (nx * ny)) as f64]);
            [p.x, p.y, p.z]
        }),
    };
    Outside { voxels, values, report }
}
