//! Binary masks on a voxel grid.

/// Whether voxel `n` or one of its face neighbours along the axes flagged in `axes` is set
/// in `flags` (first index fastest, `dims` voxels).
#[inline]
pub fn touches_along(flags: &[bool], dims: [usize; 3], axes: [bool; 3], n: usize) -> bool {
    if flags[n] {
        return true;
    }
    let stride = [1, dims[0], dims[0] * dims[1]];
    (0..3).any(|a| {
        let i = n / stride[a] % dims[a];
        axes[a] && ((i > 0 && flags[n - stride[a]]) || (i + 1 < dims[a] && flags[n + stride[a]]))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_voxel_touches_exactly_the_set_voxels_within_one_face_step_along_the_axes_asked() {
        // A few scattered voxels on a 5 × 4 × 3 grid, two on its faces; the reference is the
        // set of voxels at index (Manhattan) distance at most one from a set voxel, the step
        // along an axis that is asked for.
        let dims = [5usize, 4, 3];
        let ijk = |n: usize| [n % 5, (n / 5) % 4, n / 20];
        let set = [0usize, 13, 59, 27];
        let mut flags = vec![false; 60];
        for &s in &set {
            flags[s] = true;
        }
        for axes in [[true; 3], [true, false, true], [false, true, false], [false; 3]] {
            for n in 0..flags.len() {
                let a = ijk(n);
                let want = set.iter().any(|&s| {
                    let b = ijk(s);
                    let d: Vec<usize> = (0..3).map(|c| a[c].abs_diff(b[c])).collect();
                    let sum: usize = d.iter().sum();
                    sum == 0 || (sum == 1 && (0..3).any(|c| d[c] == 1 && axes[c]))
                });
                assert_eq!(touches_along(&flags, dims, axes, n), want, "voxel {n} {a:?} {axes:?}");
            }
        }
    }
}
