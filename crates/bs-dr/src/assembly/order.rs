//! The order in which the assembly runs the tetrahedra: along a Morton (Z-order) curve
//! through their centroids, so that neighbouring tetrahedra are neighbours in memory. A
//! mesher's order (Gmsh's Delaunay insertion order, for one) scatters a node's tetrahedra
//! over the whole element array; in Morton order a node's force slots, the displacements
//! a block of four reads and the nodal averages of T4ANP lie close together, and the
//! memory-bound force evaluation reads less.
//!
//! Only the assembly's internal order changes: every tetrahedron keeps its mesh element
//! index (`Elements::tet_elem`), through which every per-element result and message is
//! reported.

use bs_mesh::Point3;

/// Bits per axis of the Morton code (three interleaved in a `u64`).
const BITS: u32 = 21;

/// The permutation that sorts `points` along the Morton curve of their bounding box:
/// `order[i]` is the index of the `i`-th point. Ties (points in the same cell of the
/// 2²¹-per-axis lattice) keep their input order, so the result depends on the points alone.
pub(crate) fn morton_order(points: &[Point3<f64>]) -> Vec<u32> {
    let Some(first) = points.first() else { return Vec::new() };
    let (mut lo, mut hi) = (*first, *first);
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let cells = f64::from((1u32 << BITS) - 1);
    let scale: [f64; 3] =
        std::array::from_fn(|k| if hi[k] > lo[k] { cells / (hi[k] - lo[k]) } else { 0.0 });
    let code = |p: &Point3<f64>| {
        let q: [u64; 3] = std::array::from_fn(|k| ((p[k] - lo[k]) * scale[k]) as u64);
        spread(q[0]) | (spread(q[1]) << 1) | (spread(q[2]) << 2)
    };
    let mut keyed: Vec<(u64, u32)> =
        points.iter().enumerate().map(|(i, p)| (code(p), i as u32)).collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The low 21 bits of `v` spread to every third bit.
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spreading_puts_bit_k_at_bit_3k() {
        for k in 0..BITS {
            assert_eq!(spread(1 << k), 1 << (3 * k), "bit {k}");
        }
        assert_eq!(spread(0x1f_ffff), 0x1249_2492_4924_9249 & ((1 << 63) - 1));
    }

    #[test]
    fn the_corners_of_a_cube_come_in_z_order_and_ties_keep_their_order() {
        // The eight corners of the unit cube, listed in reverse Z order, and a copy of the
        // origin: Z order is x fastest, then y, then z.
        let mut pts: Vec<Point3<f64>> = (0..8)
            .rev()
            .map(|c| Point3::new(f64::from(c & 1), f64::from((c >> 1) & 1), f64::from(c >> 2)))
            .collect();
        pts.push(Point3::origin());
        let order = morton_order(&pts);
        assert_eq!(order, vec![7, 8, 6, 5, 4, 3, 2, 1, 0]);
        // A permutation, also for a degenerate (flat) box.
        let flat: Vec<Point3<f64>> =
            (0..10).map(|i| Point3::new(f64::from(9 - i), 0.0, 0.0)).collect();
        assert_eq!(morton_order(&flat), (0..10).rev().collect::<Vec<u32>>());
        assert!(morton_order(&[]).is_empty());
    }
}
