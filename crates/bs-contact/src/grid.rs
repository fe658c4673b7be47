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

/// Result of the 27-bucket block search ([`BucketGrid::block`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Block {
    /// Bucket of the query (clamped).
    pub c: [usize; 3],
    /// Nearest item found in the block (id, distance²); `u32::MAX`, ∞ when empty.
    pub best: (u32, f64),
    /// Second-nearest distance² in the block.
    pub next: f64,
    /// Every item outside the block is at least this far from the query.
    pub bound: f64,
}

/// Offers item `id` at squared distance `d2` to a running (nearest, second distance²)
/// pair. Ties are broken towards the smaller id, so the result does not depend on the
/// order in which items are visited.
#[inline]
pub fn consider(id: u32, d2: f64, best: &mut (u32, f64), next: &mut f64) {
    if d2 < best.1 || (d2 == best.1 && id < best.0) {
        *next = best.1;
        *best = (id, d2);
    } else if d2 < *next {
        *next = d2;
    }
}

/// Result of an exact nearest-item search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Item id of the nearest item (smallest id on exact ties).
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
    /// empty or `p` is not finite.
    pub fn nearest(&self, p: &Point3<f64>, second: bool) -> Option<Nearest> {
        if self.ids.is_empty() {
            return None;
        }
        self.nearest_from(p, self.block(p), second)
    }

    /// [`nearest`](Self::nearest) continued from an already computed block search.
    pub fn nearest_from(&self, p: &Point3<f64>, block: Block, second: bool) -> Option<Nearest> {
        if self.ids.is_empty() || !p.coords.iter().all(|x| x.is_finite()) {
            return None;
        }
        let Block { c, best, next, .. } = block;
        let (mut best, mut next) = (best, next);
        let visit = |range: std::ops::Range<usize>, best: &mut (u32, f64), next: &mut f64| {
            self.scan(range, p, best, next)
        };
        // Then whole shells only while nothing has been found.
        let mut r = 1;
        loop {
            let bound = self.outside_bound(p, c, r);
            let target = if second { next } else { best.1 };
            // Strict: an item exactly at the bound could win an id tie.
            if target < bound * bound {
                return Some(Nearest { id: best.0, d2: best.1, other_lb: next.sqrt().min(bound) });
            }
            if target.is_finite() {
                break;
            }
            r += 1;
            if r > self.dims.iter().copied().max().unwrap_or(0) {
                // The block covers the grid: every item has been visited.
                return Some(Nearest { id: best.0, d2: best.1, other_lb: next.sqrt() });
            }
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
                if rest < 0.0 {
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

    /// The paper's block search: P's bucket and its 26 neighbours. Buckets are stored
    /// x-fastest, so each row of the block is one contiguous range. Returns the nearest item
    /// found (ties: smallest id), the second distance², and the bound below which the block
    /// result is certified (distance from `p` to the unvisited buckets).
    #[inline]
    pub fn block(&self, p: &Point3<f64>) -> Block {
        let c = self.cell_of(p);
        let mut best = (u32::MAX, f64::INFINITY);
        let mut next = f64::INFINITY;
        let (x0, x1) = (c[0].saturating_sub(1), (c[0] + 1).min(self.dims[0] - 1));
        for z in c[2].saturating_sub(1)..=(c[2] + 1).min(self.dims[2] - 1) {
            for y in c[1].saturating_sub(1)..=(c[1] + 1).min(self.dims[1] - 1) {
                self.scan(self.row(x0, x1, y, z), p, &mut best, &mut next);
            }
        }
        Block { c, best, next, bound: self.outside_bound(p, c, 1) }
    }

    /// Updates the nearest (ties: smallest id) and second-nearest distance² with the items
    /// of `range`.
    #[inline]
    fn scan(
        &self,
        range: std::ops::Range<usize>,
        p: &Point3<f64>,
        best: &mut (u32, f64),
        next: &mut f64,
    ) {
        for (id, q) in self.ids[range.clone()].iter().zip(&self.pts[range]) {
            consider(*id, (q - p).norm_squared(), best, next);
        }
    }

    /// For every bucket, an item near its centre: the propagated nearest seed of a two-pass
    /// sweep over the 26-neighbourhood (a discrete Voronoi diagram; approximate, used only as
    /// a starting point that is then certified). `u32::MAX` for an empty grid.
    pub fn seeds(&self) -> Vec<u32> {
        let n = self.dims[0] * self.dims[1] * self.dims[2];
        let mut seed = vec![(u32::MAX, f64::INFINITY); n];
        let pt_of = |id_slot: usize| self.pts[id_slot];
        // Slot of each item id in bucket order, to look its point up.
        let max_id = self.ids.iter().copied().max().map_or(0, |m| m as usize + 1);
        let mut slot = vec![usize::MAX; max_id];
        for (k, &id) in self.ids.iter().enumerate() {
            slot[id as usize] = k;
        }
        let centre = |x: usize, y: usize, z: usize| {
            Point3::new(
                self.origin.x + (x as f64 + 0.5) * self.h.x,
                self.origin.y + (y as f64 + 0.5) * self.h.y,
                self.origin.z + (z as f64 + 0.5) * self.h.z,
            )
        };
        for z in 0..self.dims[2] {
            for y in 0..self.dims[1] {
                for x in 0..self.dims[0] {
                    let f = self.flat([x, y, z]);
                    let cc = centre(x, y, z);
                    let mut best = (u32::MAX, f64::INFINITY);
                    let mut next = f64::INFINITY;
                    self.scan(self.row(x, x, y, z), &cc, &mut best, &mut next);
                    seed[f] = best;
                }
            }
        }
        if self.ids.is_empty() {
            return vec![u32::MAX; n];
        }
        let dims = [self.dims[0] as isize, self.dims[1] as isize, self.dims[2] as isize];
        for pass in 0..2 {
            let order: Box<dyn Iterator<Item = usize>> =
                if pass == 0 { Box::new(0..n) } else { Box::new((0..n).rev()) };
            for f in order {
                let (x, y, z) = (
                    f % self.dims[0],
                    (f / self.dims[0]) % self.dims[1],
                    f / (self.dims[0] * self.dims[1]),
                );
                let cc = centre(x, y, z);
                let mut best = seed[f];
                for dz in -1isize..=1 {
                    for dy in -1isize..=1 {
                        for dx in -1isize..=1 {
                            let (nx, ny, nz) = (x as isize + dx, y as isize + dy, z as isize + dz);
                            if nx < 0
                                || ny < 0
                                || nz < 0
                                || nx >= dims[0]
                                || ny >= dims[1]
                                || nz >= dims[2]
                            {
                                continue;
                            }
                            let g = self.flat([nx as usize, ny as usize, nz as usize]);
                            let id = seed[g].0;
                            if id != u32::MAX && id != best.0 {
                                let d2 = (pt_of(slot[id as usize]) - cc).norm_squared();
                                if d2 < best.1 {
                                    best = (id, d2);
                                }
                            }
                        }
                    }
                }
                seed[f] = best;
            }
        }
        seed.into_iter().map(|s| s.0).collect()
    }

    /// Flat index of the bucket containing `p` (clamped).
    #[inline]
    pub fn flat_of(&self, p: &Point3<f64>) -> usize {
        self.flat(self.cell_of(p))
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
