//! Binary masks on a voxel grid.

/// Whether voxel `n` or one of its six face neighbours is set in `flags` (first index
/// fastest, `dims` voxels).
#[inline]
pub fn touches(flags: &[bool], dims: [usize; 3], n: usize) -> bool {
    let [nx, ny, nz] = dims;
    let (sj, sk) = (nx, nx * ny);
    if flags[n] {
        return true;
    }
    let (i, j, k) = (n % nx, (n / nx) % ny, n / sk);
    (i > 0 && flags[n - 1])
        || (i + 1 < nx && flags[n + 1])
        || (j > 0 && flags[n - sj])
        || (j + 1 < ny && flags[n + sj])
        || (k > 0 && flags[n - sk])
        || (k + 1 < nz && flags[n + sk])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_voxel_touches_exactly_the_set_voxels_within_one_face_step() {
        // A few scattered voxels on a 5 × 4 × 3 grid, two on its faces; the reference is the
        // set of voxels at index (Manhattan) distance at most one from a set voxel.
        let dims = [5usize, 4, 3];
        let ijk = |n: usize| [n % 5, (n / 5) % 4, n / 20];
        let set = [0usize, 13, 59, 27];
        let mut flags = vec![false; 60];
        for &s in &set {
            flags[s] = true;
        }
        for n in 0..flags.len() {
            let a = ijk(n);
            let want = set.iter().any(|&s| {
                let b = ijk(s);
                (0..3).map(|c| a[c].abs_diff(b[c])).sum::<usize>() <= 1
            });
            assert_eq!(touches(&flags, dims, n), want, "voxel {n} {a:?}");
        }
    }
}
