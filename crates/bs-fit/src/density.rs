//! The area each point of a scan stands for: the inverse of the local point density,
//! `a_i = π d_k² / k` with `d_k` the distance to the `k`-th nearest other point (k = 6). For
//! points of density `ρ` spread over a surface, the `k` nearest lie within a disc of area
//! about `k/ρ`, so `a_i ≈ 1/ρ` and `Σ a_i` is the scanned area, however densely the scanner
//! sampled it (for a Poisson sample `E[π d_k²] = k/ρ` exactly). A point on the scan's edge
//! sees its neighbours on one side only and would stand for twice its share; areas are
//! capped at twice the median. Found on bs-contact's bucket grid in boxes that grow until
//! they hold `k` points within their inscribed ball.

use bs_contact::grid::BucketGrid;
use bs_mesh::{Point3, Vector3};
use rayon::prelude::*;

/// Neighbours counted.
pub const K: usize = 6;

/// `π d_k² / k` for every point (see the module documentation); a scan of fewer than
/// `k + 1` points gives each the same share of its bounding box's largest face.
pub fn point_areas(points: &[Point3<f64>]) -> Vec<f64> {
    let n = points.len();
    if n == 0 {
        return Vec::new();
    }
    let (lo, hi) = points.iter().fold((points[0], points[0]), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    let e = hi - lo;
    let face = (e.x * e.y).max(e.y * e.z).max(e.x * e.z).max(f64::MIN_POSITIVE);
    if n <= K {
        return vec![face / n as f64; n];
    }
    // Buckets of about K points on a surface of the bounding box's largest face.
    let h = (face * K as f64 / n as f64).sqrt().max(1e-9 * (1.0 + e.norm()));
    let items: Vec<(u32, Point3<f64>)> =
        points.iter().enumerate().map(|(i, p)| (i as u32, *p)).collect();
    let grid = BucketGrid::new(&items, Vector3::repeat(h));
    let mut areas: Vec<f64> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let dk = kth_distance(&grid, p, i as u32, h);
            std::f64::consts::PI * dk * dk / K as f64
        })
        .collect();
    let mut sorted = areas.clone();
    let (_, median, _) = sorted.select_nth_unstable_by(n / 2, f64::total_cmp);
    let cap = 2.0 * *median;
    areas.iter_mut().for_each(|a| *a = a.min(cap));
    areas
}

/// The distance from `p` (item `me`) to its `K`-th nearest other item.
fn kth_distance(grid: &BucketGrid, p: &Point3<f64>, me: u32, h: f64) -> f64 {
    let mut r = h;
    let mut d2 = Vec::with_capacity(4 * K);
    loop {
        d2.clear();
        grid.for_each_in_box(p, r, |id, q| {
            if id != me {
                d2.push((q - p).norm_squared());
            }
        });
        // Every point within distance r is in the box: the K-th smallest distance is exact
        // once it is at most r.
        if d2.len() >= K {
            let (_, kth, _) = d2.select_nth_unstable_by(K - 1, f64::total_cmp);
            if kth.sqrt() <= r {
                return kth.sqrt();
            }
        }
        r *= 2.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square grid of spacing s: every point's area is about s², and the sum is the
    /// square's area whether it is sampled at spacing 1 or 0.5.
    #[test]
    fn areas_follow_the_density() {
        for s in [1.0, 0.5] {
            let m = (20.0 / s) as usize;
            let pts: Vec<Point3<f64>> = (0..m * m)
                .map(|k| Point3::new((k % m) as f64 * s, (k / m) as f64 * s, 0.0))
                .collect();
            let a = point_areas(&pts);
            // Interior points: the 6th neighbour of a square lattice is at s√2 (4 at s,
            // 4 at s√2): π 2s² / 6 ≈ 1.05 s².
            let interior = a[(m / 2) * m + m / 2];
            assert!((interior / (s * s) - std::f64::consts::PI / 3.0).abs() < 1e-9, "{interior}");
            // The lattice's 6th neighbour overestimates by π/3, the edges by at most 2×.
            let total: f64 = a.iter().sum();
            assert!((1.0..1.3).contains(&(total / 400.0)), "{total}");
        }
        assert_eq!(point_areas(&[]), Vec::<f64>::new());
        assert_eq!(point_areas(&[Point3::origin(), Point3::new(2.0, 1.0, 0.0)]), vec![1.0, 1.0]);
    }
}
