//! The three orthogonal planes through the largest displacement that a preview shows:
//! the pre-operative image, the warped one, |d| and the deformed brain, cut from a grid as
//! plain numbers (the front end draws them). Planes are index planes of the image grid
//! (k: axial, j: coronal, i: sagittal for an image stored in RAS-like order).

use bs_image::{Grid, Slice, Volume};

/// The three planes with the grey window and the top of the colour scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Planes {
    /// Axial, coronal, sagittal.
    pub planes: Vec<Slice>,
    /// Grey levels shown black and white (the 1st and 99.5th percentiles of the image).
    pub window: [f32; 2],
    /// The largest |d| (mm).
    pub max_mm: f64,
    /// The voxel of the largest |d|.
    pub voxel: [usize; 3],
}

/// Cuts the planes of `g` through the voxel `at` (its index; `None`: the voxel of largest
/// |d| of `field`); `in_brain(n)`: voxel `n` lies inside the deformed brain; `sigma`: σ (mm)
/// per voxel, when the result has one.
pub fn planes(
    g: &Grid,
    in_brain: &dyn Fn(usize) -> bool,
    (before, after): (&Volume<f32>, &[f32]),
    field: &[[f32; 3]],
    sigma: Option<&[f32]>,
    at: Option<usize>,
) -> Planes {
    let [nx, ny, nz] = g.dims();
    let norm = |d: &[f32; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let (best, max) = field
        .iter()
        .enumerate()
        .fold((0usize, 0.0f32), |(b, m), (n, d)| if norm(d) > m { (n, norm(d)) } else { (b, m) });
    let best = at.unwrap_or(best);
    let v = [best % nx, (best / nx) % ny, best / (nx * ny)];
    let sp = g.spacing();
    let inside = in_brain;
    // (title, width axis, height axis, fixed axis)
    let cuts = [("axial", 0, 1, 2), ("coronal", 0, 2, 1), ("sagittal", 1, 2, 0)];
    let dims = [nx, ny, nz];
    let planes = cuts
        .iter()
        .map(|&(name, a, b, fixed)| {
            let (w, h) = (dims[a], dims[b]);
            let mut p = Slice {
                title: format!("{name} ({} = {})", ["i", "j", "k"][fixed], v[fixed]),
                width: w,
                height: h,
                spacing: [sp[a], sp[b]],
                before: Vec::with_capacity(w * h),
                after: Vec::with_capacity(w * h),
                magnitude: Vec::with_capacity(w * h),
                inside: Vec::with_capacity(w * h),
                sigma: sigma.map(|_| Vec::with_capacity(w * h)),
                marker: [v[a], v[b]],
            };
            for y in 0..h {
                for x in 0..w {
                    let mut ijk = v;
                    ijk[a] = x;
                    ijk[b] = y;
                    let n = g.index(ijk[0], ijk[1], ijk[2]);
                    p.before.push(before.data[n]);
                    p.after.push(after[n]);
                    p.magnitude.push(norm(&field[n]));
                    p.inside.push(inside(n));
                    if let (Some(out), Some(s)) = (&mut p.sigma, sigma) {
                        out.push(s[n]);
                    }
                }
            }
            p
        })
        .collect();
    Planes { planes, window: window(&before.data), max_mm: max as f64, voxel: v }
}

/// The 1st and 99.5th percentiles of a subsample of the values.
fn window(data: &[f32]) -> [f32; 2] {
    let mut s: Vec<f32> = data.iter().step_by(7).copied().filter(|v| v.is_finite()).collect();
    if s.is_empty() {
        return [0.0, 1.0];
    }
    s.sort_by(f32::total_cmp);
    let at = |q: f64| s[((s.len() - 1) as f64 * q) as usize];
    let (lo, hi) = (at(0.01), at(0.995));
    if hi > lo { [lo, hi] } else { [lo, lo + 1.0] }
}
