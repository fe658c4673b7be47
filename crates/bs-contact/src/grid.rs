//! Uniform bucket grid ("bucket sort" of the paper) over a point set, with per-axis bucket
//! sizes, exact nearest-point search and box-range queries.

use nalgebra::{Point3, Vector3};

use crate::master::bounds;

/// Most buckets a grid may have; beyond it the bucket sizes are scaled up uniformly (this
/// only happens for pathological meshes whose edges are tiny compared to the model).
const MAX_CELLS: usize = 1 << 25;

/// Bucket faces are moved this fraction of a bucket towards the query when bounding the
/// distance to unvisited buckets, so that rounding in the bucket index of a point on a
/// bucket face can never make the bound optimistic.
const SLACK: f64 = 1e-9;

/// A uniform grid of buckets holding point items.
#[derive(Debug, Clone)]
pub struct BucketGrid {
    /// Lower corner of bucket (0, 0, 0).
    pub origin: Point3<f64>,
    /// Bucket size per axis.
    pub h: Vector3<f64>,
    inv_h: Vector3<f64>,
    /// Number of buckets per axis.
    pub dims: [usize; 3],
    /// CSR offsets of the buckets (x fastest).
    start: Vec<u32>,
    /// Item ids in bucket order.
    ids: Vec<u32>,
    /// Item coordinates in bucket order.
    pts: Vec<Point3<f64>>,
}

/// Result of an exact nearest-item search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Item id of the nearest item (first found on ties, in bucket scan order).
    pub id: u32,
    /// Squared distance to it.
    pub d2: f64,
    /// A lower bound on the distance to every other item (exact second-nearest distance
    /// when asked for, else the search's certified bound).
    pub other_lb: f64,
}

impl BucketGrid {
    /// Builds the grid over `items` (id, point) with bucket size `h` per axis. Sizes that are
    /// zero or not finite are replaced by the largest positive one (or 1).
    pub fn new(items: &[(u32, Point3<f64>)], h: Vector3<f64>) -> Self {
        let (lo, hi) = if items.is_empty() {
            (Point3::origin(), Point3::origin())
        } else {
            bounds(items.iter().map(|(_, p)| p))
        };
        let fallback = {
            let m = h.iter().copied().filter(|x| x.is_finite() && *x > 0.0).fold(0.0, f64::max);
            if m > 0.0 { m } else { 1.0 }
        };
        let mut h = h.map(|x| if x.is_finite() && x > 0.0 { x } else { fallback });
        let mut dims = [1usize; 3];
        loop {
            for k in 0..3 {
                dims[k] = ((hi[k] - lo[k]) / h[k]).floor() as usize + 1;
            }
            if dims.iter().product::<usize>() <= MAX_CELLS {
                break;
            }
            h *= 2.0;
        }
        let inv_h = h.map(|x| 1.0 / x);
        let mut grid = Self {
            origin: lo,
            h,
            inv_h,
            dims,
            start: vec![0; dims[0] * dims[1] * dims[2] + 1],
            ids: vec![0; items.len()],
            pts: vec![Point3::origin(); items.len()],
        };
        let cells: Vec<usize> = items.iter().map(|(_, p)| grid.flat(grid.cell_of(p))).collect();
        for &c in &cells {
            grid.start[c + 1] += 1;
        }
        for i in 0..grid.start.len() - 1 {
            grid.start[i + 1] += grid.start[i];
        }
        let mut fill = grid.start.clone();
        for (k, &c) in cells.iter().enumerate() {
            let slot = fill[c] as usize;
            grid.ids[slot] = items[k].0;
            grid.pts[slot] = items[k].1;
            fill[c] += 1;
        }
        grid
    }

    /// Bucket of a point, clamped to the grid.
    #[inline]
    pub fn cell_of(&self, p: &Point3<f64>) -> [usize; 3] {
        [self.index_on(0, p.x), self.index_on(1, p.y), self.index_on(2, p.z)]
    }

    /// Bucket index of coordinate `x` on `axis`, clamped to the grid.
    #[inline]
    fn index_on(&self, axis: usize, x: f64) -> usize {
        let i = ((x - self.origin[axis]) * self.inv_h[axis]).floor();
        if i <= 0.0 || i.is_nan() { 0 } else { (i as usize).min(self.dims[axis] - 1) }
    }

    #[inline]
    fn flat(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    /// Lower bound on the distance from `p` to any item outside the bucket block
    /// `[c − r, c + r]` (clamped to the grid); infinity if the block covers the grid.
    #[inline]
    fn outside_bound(&self, p: &Point3<f64>, c: [usize; 3], r: usize) -> f64 {
        let mut bound = f64::INFINITY;
        for k in 0..3 {
            if c[k] > r {
                let face = self.origin[k] + (c[k] - r) as f64 * self.h[k];
                bound = bound.min((p[k] - face - SLACK * self.h[k]).max(0.0));
            }
            if c[k] + r + 1 < self.dims[k] {
                let face = self.origin[k] + (c[k] + r + 1) as f64 * self.h[k];
                bound = bound.min((face - p[k] - SLACK * self.h[k]).max(0.0));
            }
        }
        bound
    }

    /// Calls `f` with the item ranges of every bucket at Chebyshev index distance exactly
    /// `r` from `c` (whole rows where the row lies on the shell).
    #[inline]
    fn for_shell(&self, c: [usize; 3], r: usize, mut f: impl FnMut(std::ops::Range<usize>)) {
        let lo = |k: usize| c[k].saturating_sub(r);
        let hi = |k: usize| (c[k] + r).min(self.dims[k] - 1);
        for z in lo(2)..=hi(2) {
            let dz = z.abs_diff(c[2]);
            for y in lo(1)..=hi(1) {
                let dy = y.abs_diff(c[1]);
                if dz == r || dy == r {
                    f(self.row(lo(0), hi(0), y, z));
                } else {
                    // Only the two x-ends of the row are on the shell.
                    if c[0] >= r {
                        f(self.row(c[0] - r, c[0] - r, y, z));
                    }
                    if r > 0 && c[0] + r < self.dims[0] {
                        f(self.row(c[0] + r, c[0] + r, y, z));
                    }
                }
            }
        }
    }

    /// Exact nearest item to `p`: the bucket of `p` and its 26 neighbours first (the paper's
    /// search), then further shells of buckets until the nearest found is certified closer
    /// than anything unvisited. A point outside the grid is clamped to the nearest bucket and
    /// the same certification applies, so it also gets the exact answer. With `second`, the
    /// search goes on until the second-nearest distance is exact too. `None` if the grid is
    /// empty.
    pub fn nearest(&self, p: &Point3<f64>, second: bool) -> Option<Nearest> {
        if self.ids.is_empty() {
            return None;
        }
        let c = self.cell_of(p);
        let mut best = (u32::MAX, f64::INFINITY);
        let mut next = f64::INFINITY;
        let visit = |range: std::ops::Range<usize>, best: &mut (u32, f64), next: &mut f64| {
            for (id, q) in self.ids[range.clone()].iter().zip(&self.pts[range]) {
                let d2 = (q - p).norm_squared();
                if d2 < best.1 {
                    *next = best.1;
                    *best = (*id, d2);
                } else if d2 < *next {
                    *next = d2;
                }
            }
        };
        // The paper's block: P's bucket and its 26 neighbours. Buckets are stored x-fastest,
        // so each row of the block is one contiguous range.
        let (x0, x1) = (c[0].saturating_sub(1), (c[0] + 1).min(self.dims[0] - 1));
        for z in c[2].saturating_sub(1)..=(c[2] + 1).min(self.dims[2] - 1) {
            for y in c[1].saturating_sub(1)..=(c[1] + 1).min(self.dims[1] - 1) {
                visit(self.row(x0, x1, y, z), &mut best, &mut next);
            }
        }
        // Then whole shells only while nothing has been found.
        let mut r = 1;
        loop {
            let bound = self.outside_bound(p, c, r);
            let target = if second { next } else { best.1 };
            if target <= bound * bound {
                return Some(Nearest { id: best.0, d2: best.1, other_lb: next.sqrt().min(bound) });
            }
            if target.is_finite() {
                break;
            }
            r += 1;
            self.for_shell(c, r, |range| visit(range, &mut best, &mut next));
        }
        // Certification: visit the buckets outside the block that intersect the ball of the
        // current target radius (the target only shrinks, so the ranges computed from it are
        // supersets), row by row, each row cut to the ball and split around the block.
        let target = |best: &(u32, f64), next: f64| if second { next } else { best.1 };
        let rad = target(&best, next).sqrt();
        let lo = self.cell_of(&(p - Vector3::repeat(rad)));
        let hi = self.cell_of(&(p + Vector3::repeat(rad)));
        for z in lo[2]..=hi[2] {
            let dz = self.axis_gap(p, 2, z);
            for y in lo[1]..=hi[1] {
                let dy = self.axis_gap(p, 1, y);
                let rest = target(&best, next) - (dz * dz + dy * dy);
                if rest <= 0.0 {
                    continue;
                }
                let w = rest.sqrt();
                let xa = self.index_on(0, p.x - w);
                let xb = self.index_on(0, p.x + w);
                if z.abs_diff(c[2]) <= r && y.abs_diff(c[1]) <= r {
                    // Skip the part of the row inside the block.
                    let (bl, bh) = (c[0].saturating_sub(r), c[0] + r);
                    if xa < bl {
                        visit(self.row(xa, (bl - 1).min(xb), y, z), &mut best, &mut next);
                    }
                    if xb > bh {
                        visit(self.row(xa.max(bh + 1), xb, y, z), &mut best, &mut next);
                    }
                } else {
                    visit(self.row(xa, xb, y, z), &mut best, &mut next);
                }
            }
        }
        // Every item not visited is at least √target away.
        let lb = if second { next.sqrt() } else { best.1.sqrt() };
        Some(Nearest { id: best.0, d2: best.1, other_lb: lb })
    }

    /// Item range of the buckets `x0..=x1` of row (y, z).
    #[inline]
    fn row(&self, x0: usize, x1: usize, y: usize, z: usize) -> std::ops::Range<usize> {
        let base = self.dims[0] * (y + self.dims[1] * z);
        self.start[base + x0] as usize..self.start[base + x1 + 1] as usize
    }

    /// Distance from `p` to the slab of bucket index `i` on `axis` (0 inside), with the
    /// rounding slack.
    #[inline]
    fn axis_gap(&self, p: &Point3<f64>, axis: usize, i: usize) -> f64 {
        let lo = self.origin[axis] + (i as f64 - SLACK) * self.h[axis];
        let hi = self.origin[axis] + (i as f64 + 1.0 + SLACK) * self.h[axis];
        (lo - p[axis]).max(p[axis] - hi).max(0.0)
    }

    /// Calls `f(id)` for every item whose point lies within the axis-aligned box
    /// `[q − radius, q + radius]` (a superset of the ball of that radius).
    pub fn for_each_in_box(
        &self,
        q: &Point3<f64>,
        radius: f64,
        mut f: impl FnMut(u32, &Point3<f64>),
    ) {
        if self.ids.is_empty() {
            return;
        }
        let lo = self.cell_of(&(q - Vector3::repeat(radius)));
        let hi = self.cell_of(&(q + Vector3::repeat(radius)));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                let range = self.row(lo[0], hi[0], y, z);
                for (id, p) in self.ids[range.clone()].iter().zip(&self.pts[range]) {
                    f(*id, p);
                }
            }
        }
    }
}
