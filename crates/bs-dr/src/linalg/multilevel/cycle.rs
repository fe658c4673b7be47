//! Applying the preconditioner: one symmetric V-cycle `x = B b` for `Π K Π`. On every level
//! above the coarsest: Chebyshev pre-smoothing, the coarse correction (restriction, the
//! cycle of the level below, prolongation), Chebyshev post-smoothing; the coarsest level is
//! solved exactly. The operators and prolongators are read in single precision, the
//! vectors and sums kept in double; caller-owned scratch.

use bs_mesh::Vector3;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::LltRef;
use faer::{Conj, MatMut, Par};
use nalgebra::SVector;
use rayon::prelude::*;

use super::blocks::Blocks;
use super::constraints::Constraints;
use super::levels::{Level, Levels, Matrix6f};
use super::operator::{BatchScratch, OperatorScratch};
use super::projector::Projector;
use super::setup::Multilevel;
use crate::linalg::sparse::batch_chunks;

/// Nodes per rayon task in the mesh level's passes: few enough tasks that the fork-join
/// overhead stays small next to the work of a pass.
const ROWS: usize = 2048;

/// Coarse nodes per rayon task.
const COARSE_ROWS: usize = 64;

/// The six unknowns of a coarse node.
pub(crate) type V6 = SVector<f64, 6>;

/// Caller-owned buffers of [`Multilevel::apply`].
pub struct MultilevelScratch {
    r: Vec<Vector3<f64>>,
    d: Vec<Vector3<f64>>,
    t: Vec<Vector3<f64>>,
    e: Vec<Vector3<f64>>,
    k: OperatorScratch,
    /// Per coarse level: right-hand side, solution, residual and two Chebyshev vectors.
    levels: Vec<[Vec<V6>; 5]>,
    coarsest: Vec<f64>,
    mem: MemBuffer,
}

impl std::fmt::Debug for MultilevelScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MultilevelScratch")
            .field("nodes", &self.r.len())
            .field("levels", &self.levels.len())
            .field("coarsest", &self.coarsest.len())
            .finish()
    }
}

/// Caller-owned buffers of [`Multilevel::apply_batch`]: the cycle's vectors of each of the
/// `K` right-hand sides, and the batch product's.
pub struct MultilevelBatchScratch<const K: usize> {
    r: [Vec<Vector3<f64>>; K],
    d: [Vec<Vector3<f64>>; K],
    t: [Vec<Vector3<f64>>; K],
    e: [Vec<Vector3<f64>>; K],
    k: BatchScratch<K>,
    /// Per coarse level, per vector: right-hand side, solution, residual and two Chebyshev
    /// vectors.
    levels: Vec<[[Vec<V6>; 5]; K]>,
    /// The coarsest level's `K` right-hand sides, column after column.
    coarsest: Vec<f64>,
    mem: MemBuffer,
}

impl<const K: usize> std::fmt::Debug for MultilevelBatchScratch<K> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MultilevelBatchScratch")
            .field("vectors", &K)
            .field("nodes", &self.r[0].len())
            .finish_non_exhaustive()
    }
}

impl Multilevel {
    /// Unknowns (in nodes) of each coarse level, the first one first.
    fn coarse_sizes(&self) -> Vec<usize> {
        let st = &self.structure;
        let mut sizes = vec![st.pt32.rows()];
        sizes.extend(st.coarse.links.iter().map(|l| l.pt.rows()));
        sizes
    }

    /// Per coarse level the five vectors of its cycle.
    fn coarse_vectors(&self) -> Vec<[Vec<V6>; 5]> {
        let sizes = self.coarse_sizes();
        sizes.iter().map(|&m| std::array::from_fn(|_| vec![V6::zeros(); m])).collect()
    }

    /// The coarsest solve's buffers for `k` right-hand sides.
    fn coarsest_buffers(&self, k: usize) -> (Vec<f64>, MemBuffer) {
        let coarsest = 6 * self.coarse_sizes().last().copied().unwrap_or(0);
        let need = self.levels.levels.symbolic.solve_in_place_scratch::<f64>(k, Par::Seq);
        (vec![0.0; k * coarsest], MemBuffer::new(need))
    }

    /// Scratch buffers for [`apply`](Self::apply).
    pub fn scratch(&self) -> MultilevelScratch {
        let n = self.structure.p32.rows();
        let (coarsest, mem) = self.coarsest_buffers(1);
        MultilevelScratch {
            r: vec![Vector3::zeros(); n],
            d: vec![Vector3::zeros(); n],
            t: vec![Vector3::zeros(); n],
            e: vec![Vector3::zeros(); n],
            k: self.op32.scratch(),
            levels: self.coarse_vectors(),
            coarsest,
            mem,
        }
    }

    /// Scratch buffers for [`apply_batch`](Self::apply_batch) of `K` vectors.
    pub fn batch_scratch<const K: usize>(&self) -> MultilevelBatchScratch<K> {
        let n = self.structure.p32.rows();
        let vectors = || std::array::from_fn(|_| vec![Vector3::zeros(); n]);
        let (coarsest, mem) = self.coarsest_buffers(K);
        let sizes = self.coarse_sizes();
        let levels = sizes
            .iter()
            .map(|&m| std::array::from_fn(|_| std::array::from_fn(|_| vec![V6::zeros(); m])))
            .collect();
        MultilevelBatchScratch {
            r: vectors(),
            d: vectors(),
            t: vectors(),
            e: vectors(),
            k: self.op32.batch_scratch(),
            levels,
            coarsest,
            mem,
        }
    }

    /// Bytes one [`apply`](Self::apply) moves, counted from the sizes of what it reads and
    /// writes (each pass once; what stays in cache between passes counted again): on the
    /// mesh `2 (degree − 1) + 2` operator products and the Chebyshev updates (five nodal
    /// vectors each), the restriction and prolongation (the single-precision blocks, 4
    /// bytes of index each), on every smoothed coarse level the same with its 6 × 6 blocks,
    /// and the coarsest factor read twice (forward and back substitution). A lower bound
    /// of the memory traffic, for the distance to the machine's bandwidth.
    pub fn bytes_per_cycle(&self) -> usize {
        let st = &self.structure;
        let d = self.params.degree.max(1);
        let products = 2 * (d - 1) + 2;
        let dc = self.params.coarse_degree.max(1);
        let coarse_products = 2 * (dc - 1) + 2;
        let n = st.p32.rows();
        let fine = products * self.op32.bytes() + 2 * d * 5 * 24 * n;
        let transfer = |blocks: usize, block: usize| blocks * (block + 4);
        let mut bytes = fine + transfer(st.p32.len(), 72) + transfer(st.pt32.len(), 72);
        let levels = &self.levels.levels;
        for (level, link) in levels.smoothed.iter().zip(&st.coarse.links) {
            let m = level.a32.rows();
            bytes += coarse_products * transfer(level.a32.len(), 144)
                + 2 * dc * 5 * 48 * m
                + transfer(link.p32.len(), 144)
                + transfer(link.pt32.len(), 144);
        }
        bytes + 2 * 8 * levels.factor.len()
    }

    /// `f(a, (Π K x)_a)` for every node `a` (single-precision operator; `x` in the range
    /// of `Π`).
    fn op_with(
        &self,
        pi: &Projector,
        x: &[Vector3<f64>],
        s: &mut OperatorScratch,
        out: &mut [Vector3<f64>],
        f: impl Fn(usize, &mut Vector3<f64>, Vector3<f64>) + Sync,
    ) {
        self.op32.apply_with(x, s, out, |a, o, y| {
            let y = if pi.constrained[a] { pi.matrix[a] * y } else { y };
            f(a, o, y);
        });
    }

    /// Chebyshev smoothing from zero on the mesh: `x += p(D⁻¹A) D⁻¹ r`; `r` is overwritten.
    #[allow(clippy::too_many_arguments)]
    fn chebyshev(
        &self,
        con: &Constraints,
        r: &mut [Vector3<f64>],
        x: &mut [Vector3<f64>],
        d: &mut [Vector3<f64>],
        t: &mut [Vector3<f64>],
        s: &mut OperatorScratch,
    ) {
        let c = Chebyshev::new(self.lambda_max, self.params.lower);
        let (inv, pi) = (&con.inv_diag, &con.projector);
        chebyshev_first(inv, &c, r, x, d);
        let mut rho = 1.0 / c.sigma;
        for _ in 1..self.params.degree {
            self.op_with(pi, d, s, t, |_, ta, y| *ta = y);
            let (c1, c2, next) = c.step(rho);
            chebyshev_step(inv, (c1, c2), r, d, t, x);
            rho = next;
        }
    }

    /// [`chebyshev`](Self::chebyshev) of the `K` vectors of `s.r` into `x`, their products
    /// in one batch.
    fn chebyshev_batch<const K: usize>(
        &self,
        con: &Constraints,
        x: &mut [&mut [Vector3<f64>]; K],
        s: &mut MultilevelBatchScratch<K>,
    ) {
        let c = Chebyshev::new(self.lambda_max, self.params.lower);
        let (inv, pi) = (&con.inv_diag, &con.projector);
        for j in 0..K {
            chebyshev_first(inv, &c, &s.r[j], x[j], &mut s.d[j]);
        }
        let mut rho = 1.0 / c.sigma;
        for _ in 1..self.params.degree {
            let d = s.d.each_ref().map(|v| &v[..]);
            let t = s.t.each_mut().map(|v| &mut v[..]);
            self.op_batch(pi, d, &mut s.k, t, |_, _, ta, y| *ta = y);
            let (c1, c2, next) = c.step(rho);
            for j in 0..K {
                chebyshev_step(inv, (c1, c2), &mut s.r[j], &mut s.d[j], &s.t[j], x[j]);
            }
            rho = next;
        }
    }

    /// `x = B b`: one symmetric cycle for `Π K Π`, `b` in the range of `Π`.
    pub fn apply(
        &self,
        con: &Constraints,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        s: &mut MultilevelScratch,
    ) {
        let MultilevelScratch { r, d, t, e, k, levels, coarsest, mem } = s;
        let pi = &con.projector;
        x.par_iter_mut().with_min_len(ROWS).for_each(|v| *v = Vector3::zeros());
        r.copy_from_slice(b);
        self.chebyshev(con, r, x, d, t, k);
        // Residual after pre-smoothing, coarse correction, and the residual after it.
        self.op_with(pi, x, k, r, |a, ra, y| *ra = b[a] - y);
        let numbers = &con.levels.as_ref().unwrap_or(&self.levels).levels;
        let st = &self.structure;
        let (first, rest) = levels.split_first_mut().expect("a coarse level");
        restrict(&st.pt32, r, &mut first[0]);
        self.coarse_cycle(numbers, 0, first, rest, coarsest, mem);
        prolong(&st.p32, &first[1], e);
        pi.apply(e);
        x.par_iter_mut().zip(e.par_iter()).with_min_len(ROWS).for_each(|(xa, ea)| *xa += ea);
        self.op_with(pi, e, k, r, |_, ra, y| *ra -= y);
        // Post-smoothing accumulates into x directly.
        self.chebyshev(con, r, x, d, t, k);
    }

    /// `x_j = B b_j` for `K` right-hand sides at once: [`apply`](Self::apply) of each, with
    /// the mesh level's products of all of them in one pass over its operator (the cycle's
    /// cost on the mesh is that operator's bytes, read once here for the `K`). The results
    /// are [`apply`](Self::apply)'s to the last bit.
    pub fn apply_batch<const K: usize>(
        &self,
        con: &Constraints,
        b: [&[Vector3<f64>]; K],
        mut x: [&mut [Vector3<f64>]; K],
        s: &mut MultilevelBatchScratch<K>,
    ) {
        let pi = &con.projector;
        for (xj, (rj, bj)) in x.iter_mut().zip(s.r.iter_mut().zip(b)) {
            xj.par_iter_mut().with_min_len(ROWS).for_each(|v| *v = Vector3::zeros());
            rj.copy_from_slice(bj);
        }
        self.chebyshev_batch(con, &mut x, s);
        let xs = x.each_ref().map(|v| &v[..]);
        let r = s.r.each_mut().map(|v| &mut v[..]);
        self.op_batch(pi, xs, &mut s.k, r, |j, a, ra, y| *ra = b[j][a] - y);
        let numbers = &con.levels.as_ref().unwrap_or(&self.levels).levels;
        let st = &self.structure;
        let first = &mut s.levels[0];
        let r = s.r.each_ref().map(|v| &v[..]);
        restrict_batch(&st.pt32, r, first.each_mut().map(|h| &mut h[0][..]));
        self.coarse_cycle_batch(numbers, 0, &mut s.levels, &mut s.coarsest, &mut s.mem);
        let first = s.levels[0].each_ref().map(|h| &h[1][..]);
        prolong_batch(&st.p32, first, s.e.each_mut().map(|v| &mut v[..]));
        for (xj, e) in x.iter_mut().zip(&mut s.e) {
            pi.apply(e);
            xj.par_iter_mut().zip(e.par_iter()).with_min_len(ROWS).for_each(|(xa, ea)| {
                *xa += ea;
            });
        }
        let e = s.e.each_ref().map(|v| &v[..]);
        let r = s.r.each_mut().map(|v| &mut v[..]);
        self.op_batch(pi, e, &mut s.k, r, |_, _, ra, y| *ra -= y);
        self.chebyshev_batch(con, &mut x, s);
    }

    /// [`op_with`](Self::op_with) of `K` vectors in one pass: `f(j, a, out_j_a, (Π K x_j)_a)`.
    fn op_batch<const K: usize>(
        &self,
        pi: &Projector,
        x: [&[Vector3<f64>]; K],
        s: &mut BatchScratch<K>,
        out: [&mut [Vector3<f64>]; K],
        f: impl Fn(usize, usize, &mut Vector3<f64>, Vector3<f64>) + Sync,
    ) {
        self.op32.apply_batch(x, s, out, |j, a, o, y| {
            let y = if pi.constrained[a] { pi.matrix[a] * y } else { y };
            f(j, a, o, y);
        });
    }

    /// [`coarse_cycle`](Self::coarse_cycle) of level `l` for `K` vectors, `levels[0]` being
    /// level `l`'s buffers: the products of each level in one pass over its blocks.
    fn coarse_cycle_batch<const K: usize>(
        &self,
        numbers: &Levels,
        l: usize,
        levels: &mut [[[Vec<V6>; 5]; K]],
        coarsest: &mut [f64],
        mem: &mut MemBuffer,
    ) {
        let (here, below) = levels.split_first_mut().expect("a level");
        let Some(level) = numbers.smoothed.get(l) else {
            return solve_coarsest_batch(numbers, here, coarsest, mem);
        };
        let link = &self.structure.coarse.links[l];
        for [b, x, r, ..] in here.iter_mut() {
            x.iter_mut().for_each(|v| *v = V6::zeros());
            r.copy_from_slice(b);
        }
        let degree = self.params.coarse_degree;
        chebyshev6_batch(level, self.params.lower, degree, here);
        residual6_batch(&level.a32, here);
        let next = &mut below[0];
        let r = here.each_ref().map(|h| &h[2][..]);
        restrict_batch(&link.pt32, r, next.each_mut().map(|h| &mut h[0][..]));
        self.coarse_cycle_batch(numbers, l + 1, below, coarsest, mem);
        let next = below[0].each_ref().map(|h| &h[1][..]);
        let d = here.each_mut().map(|h| &mut h[3][..]);
        prolong_batch(&link.p32, next, d);
        for [_, x, _, d, _] in here.iter_mut() {
            x.iter_mut().zip(d.iter()).for_each(|(xi, di)| *xi += di);
        }
        residual6_batch(&level.a32, here);
        chebyshev6_batch(level, self.params.lower, degree, here);
    }

    /// The cycle of coarse level `l` (0: the first): `here[1] = B_l here[0]`.
    fn coarse_cycle(
        &self,
        numbers: &Levels,
        l: usize,
        here: &mut [Vec<V6>; 5],
        below: &mut [[Vec<V6>; 5]],
        coarsest: &mut [f64],
        mem: &mut MemBuffer,
    ) {
        let Some(level) = numbers.smoothed.get(l) else {
            return solve_coarsest(numbers, here, coarsest, mem);
        };
        let link = &self.structure.coarse.links[l];
        let [b, x, r, d, t] = here;
        x.iter_mut().for_each(|v| *v = V6::zeros());
        r.copy_from_slice(b);
        let degree = self.params.coarse_degree;
        chebyshev6(level, self.params.lower, degree, r, x, d, t);
        residual6(&level.a32, b, x, r);
        let (next, rest) = below.split_first_mut().expect("the level below");
        restrict(&link.pt32, r, &mut next[0]);
        self.coarse_cycle(numbers, l + 1, next, rest, coarsest, mem);
        prolong(&link.p32, &next[1], d);
        x.iter_mut().zip(d.iter()).for_each(|(xi, di)| *xi += di);
        residual6(&level.a32, b, x, r);
        chebyshev6(level, self.params.lower, degree, r, x, d, t);
    }
}

/// The Chebyshev recurrence on `[lower λ, λ]`.
struct Chebyshev {
    theta: f64,
    delta: f64,
    sigma: f64,
}

impl Chebyshev {
    fn new(lambda: f64, lower: f64) -> Self {
        let lo = lambda * lower;
        let theta = 0.5 * (lambda + lo);
        let delta = 0.5 * (lambda - lo);
        Chebyshev { theta, delta, sigma: theta / delta }
    }

    /// The coefficients of the next step from `rho`: `(c1, c2, rho_next)`.
    fn step(&self, rho: f64) -> (f64, f64, f64) {
        let next = 1.0 / (2.0 * self.sigma - rho);
        (next * rho, 2.0 * next / self.delta, next)
    }
}

/// The first Chebyshev step on the mesh from `x`'s start: `d = D⁻¹ r / θ`, `x += d`.
fn chebyshev_first(
    inv: &[nalgebra::Matrix3<f64>],
    c: &Chebyshev,
    r: &[Vector3<f64>],
    x: &mut [Vector3<f64>],
    d: &mut [Vector3<f64>],
) {
    d.par_iter_mut()
        .zip(r.par_iter())
        .zip(x.par_iter_mut())
        .enumerate()
        .with_min_len(ROWS)
        .for_each(|(a, ((da, ra), xa))| {
            *da = inv[a] * ra / c.theta;
            *xa += *da;
        });
}

/// A further Chebyshev step on the mesh with `t = A d`: `r −= t`, `d = c1 d + c2 D⁻¹ r`,
/// `x += d`.
fn chebyshev_step(
    inv: &[nalgebra::Matrix3<f64>],
    (c1, c2): (f64, f64),
    r: &mut [Vector3<f64>],
    d: &mut [Vector3<f64>],
    t: &[Vector3<f64>],
    x: &mut [Vector3<f64>],
) {
    r.par_iter_mut()
        .zip(d.par_iter_mut())
        .zip(t.par_iter())
        .zip(x.par_iter_mut())
        .enumerate()
        .with_min_len(ROWS)
        .for_each(|(a, (((ra, da), ta), xa))| {
            *ra -= ta;
            *da = *da * c1 + inv[a] * *ra * c2;
            *xa += *da;
        });
}

/// Chebyshev smoothing of a coarse level: `x += p(D⁻¹A) D⁻¹ r`, `r` overwritten.
fn chebyshev6(
    level: &Level,
    lower: f64,
    degree: usize,
    r: &mut [V6],
    x: &mut [V6],
    d: &mut [V6],
    t: &mut [V6],
) {
    let c = Chebyshev::new(level.lambda, lower);
    let inv = &level.inv_diag;
    chebyshev6_first(inv, &c, r, x, d);
    let mut rho = 1.0 / c.sigma;
    for _ in 1..degree {
        multiply6(&level.a32, d, t);
        let (c1, c2, next) = c.step(rho);
        chebyshev6_step(inv, (c1, c2), r, d, t, x);
        rho = next;
    }
}

/// The first coarse Chebyshev term: `d = D⁻¹ r / θ`, `x += d`.
fn chebyshev6_first(inv: &[Matrix6f], c: &Chebyshev, r: &[V6], x: &mut [V6], d: &mut [V6]) {
    d.par_iter_mut()
        .zip(r.par_iter())
        .zip(x.par_iter_mut())
        .enumerate()
        .with_min_len(COARSE_ROWS)
        .for_each(|(i, ((di, ri), xi))| {
            *di = inv[i].cast::<f64>() * ri / c.theta;
            *xi += *di;
        });
}

/// One coarse Chebyshev step after the product `t = A d`: `r -= t`,
/// `d = c1 d + c2 D⁻¹ r`, `x += d`.
fn chebyshev6_step(
    inv: &[Matrix6f],
    (c1, c2): (f64, f64),
    r: &mut [V6],
    d: &mut [V6],
    t: &[V6],
    x: &mut [V6],
) {
    r.par_iter_mut()
        .zip(d.par_iter_mut())
        .zip(t.par_iter())
        .zip(x.par_iter_mut())
        .enumerate()
        .with_min_len(COARSE_ROWS)
        .for_each(|(i, (((ri, di), ti), xi))| {
            *ri -= ti;
            *di = *di * c1 + inv[i].cast::<f64>() * *ri * c2;
            *xi += *di;
        });
}

/// [`chebyshev6`] of `K` vectors (`here[j]`: right-hand side, solution, residual and the
/// two Chebyshev vectors), their products in one pass.
fn chebyshev6_batch<const K: usize>(
    level: &Level,
    lower: f64,
    degree: usize,
    here: &mut [[Vec<V6>; 5]; K],
) {
    let c = Chebyshev::new(level.lambda, lower);
    let inv = &level.inv_diag;
    for [_, x, r, d, _] in here.iter_mut() {
        chebyshev6_first(inv, &c, r, x, d);
    }
    let mut rho = 1.0 / c.sigma;
    for _ in 1..degree {
        let (d, t) = split_batch(here, 3, 4);
        multiply6_batch(&level.a32, d, t);
        let (c1, c2, next) = c.step(rho);
        for [_, x, r, d, t] in here.iter_mut() {
            chebyshev6_step(inv, (c1, c2), r, d, t, x);
        }
        rho = next;
    }
}

/// Vector `read` of every `here[j]` to read and vector `write` to write (`read ≠ write`).
#[allow(clippy::type_complexity)]
fn split_batch<const K: usize>(
    here: &mut [[Vec<V6>; 5]; K],
    read: usize,
    write: usize,
) -> ([&[V6]; K], [&mut [V6]; K]) {
    assert_ne!(read, write);
    let mut pairs = here.each_mut().map(|h| {
        let (lo, hi) = h.split_at_mut(read.max(write));
        let (a, b) = (&mut lo[read.min(write)], &mut hi[0]);
        if read < write {
            (Some(&a[..]), Some(&mut b[..]))
        } else {
            (Some(&b[..]), Some(&mut a[..]))
        }
    });
    let r = std::array::from_fn(|j| pairs[j].0.take().expect("each once"));
    let w = std::array::from_fn(|j| pairs[j].1.take().expect("each once"));
    (r, w)
}

/// `here[j][2] = here[j][0] − A here[j][1]` for every `j`, the products in one pass.
fn residual6_batch<const K: usize>(a: &Blocks<f32, 6, 6>, here: &mut [[Vec<V6>; 5]; K]) {
    let (x, r) = split_batch(here, 1, 2);
    multiply6_batch(a, x, r);
    for [b, _, r, ..] in here.iter_mut() {
        r.iter_mut().zip(b.iter()).for_each(|(ri, bi)| *ri = bi - *ri);
    }
}

/// `y_j = A x_j` on a coarse level for `K` vectors, each block read and widened once.
fn multiply6_batch<const K: usize>(a: &Blocks<f32, 6, 6>, x: [&[V6]; K], y: [&mut [V6]; K]) {
    restrict_batch(a, x, y);
}

/// [`restrict`] of `K` vectors (any product of 6-row blocks into a coarse level), each
/// block read and widened once.
fn restrict_batch<const R: usize, const K: usize>(
    pt: &Blocks<f32, 6, R>,
    r: [&[SVector<f64, R>]; K],
    c: [&mut [V6]; K],
) {
    let tasks = batch_chunks(c, COARSE_ROWS);
    tasks.into_par_iter().enumerate().for_each(|(t, cs)| {
        for k in 0..cs[0].len() {
            let (nodes, vals) = pt.row(t * COARSE_ROWS + k);
            let mut acc = [V6::zeros(); K];
            for (&a, b) in nodes.iter().zip(vals) {
                let b = b.cast::<f64>();
                for j in 0..K {
                    acc[j] += b * r[j][a as usize];
                }
            }
            for j in 0..K {
                cs[j][k] = acc[j];
            }
        }
    });
}

/// [`prolong`] of `K` vectors, each block read and widened once.
fn prolong_batch<const R: usize, const K: usize>(
    p: &Blocks<f32, R, 6>,
    x: [&[V6]; K],
    e: [&mut [SVector<f64, R>]; K],
) {
    let tasks = batch_chunks(e, 256);
    tasks.into_par_iter().enumerate().for_each(|(t, es)| {
        for k in 0..es[0].len() {
            let (cols, vals) = p.row(t * 256 + k);
            let mut acc = [SVector::<f64, R>::zeros(); K];
            for (&c, b) in cols.iter().zip(vals) {
                let b = b.cast::<f64>();
                for j in 0..K {
                    acc[j] += b * x[j][c as usize];
                }
            }
            for j in 0..K {
                es[j][k] = acc[j];
            }
        }
    });
}

/// `here[j][1] = A⁻¹ here[j][0]` on the coarsest level, the `K` right-hand sides in one
/// solve (the factor read once for all of them).
fn solve_coarsest_batch<const K: usize>(
    numbers: &Levels,
    here: &mut [[Vec<V6>; 5]; K],
    c: &mut [f64],
    mem: &mut MemBuffer,
) {
    let m = 6 * here[0][0].len();
    for (j, [b, ..]) in here.iter().enumerate() {
        for (i, v) in b.iter().enumerate() {
            c[j * m + 6 * i..j * m + 6 * i + 6].copy_from_slice(v.as_slice());
        }
    }
    let llt = LltRef::new(&numbers.symbolic, &numbers.factor);
    let need = numbers.symbolic.solve_in_place_scratch::<f64>(K, Par::Seq);
    if mem.len() < need.unaligned_bytes_required() {
        *mem = MemBuffer::new(need);
    }
    llt.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(&mut c[..K * m], m, K),
        Par::Seq,
        MemStack::new(mem),
    );
    for (j, [_, x, ..]) in here.iter_mut().enumerate() {
        for (i, v) in x.iter_mut().enumerate() {
            *v = V6::from_column_slice(&c[j * m + 6 * i..j * m + 6 * i + 6]);
        }
    }
}

/// `y = A x` on a coarse level.
fn multiply6(a: &Blocks<f32, 6, 6>, x: &[V6], y: &mut [V6]) {
    y.par_iter_mut().enumerate().with_min_len(COARSE_ROWS).for_each(|(i, yi)| {
        let (cols, vals) = a.row(i);
        let mut acc = V6::zeros();
        for (&j, b) in cols.iter().zip(vals) {
            acc += b.cast::<f64>() * x[j as usize];
        }
        *yi = acc;
    });
}

/// `r = b − A x` on a coarse level.
fn residual6(a: &Blocks<f32, 6, 6>, b: &[V6], x: &[V6], r: &mut [V6]) {
    multiply6(a, x, r);
    r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
}

/// `c = Pᵀ r` through the transpose's rows (`R` rows per fine node).
fn restrict<const R: usize>(pt: &Blocks<f32, 6, R>, r: &[SVector<f64, R>], c: &mut [V6]) {
    c.par_iter_mut().enumerate().with_min_len(COARSE_ROWS).for_each(|(i, ci)| {
        let (nodes, vals) = pt.row(i);
        let mut acc = V6::zeros();
        for (&a, b) in nodes.iter().zip(vals) {
            acc += b.cast::<f64>() * r[a as usize];
        }
        *ci = acc;
    });
}

/// `e = P x` through the prolongator's rows.
fn prolong<const R: usize>(p: &Blocks<f32, R, 6>, x: &[V6], e: &mut [SVector<f64, R>]) {
    e.par_iter_mut().enumerate().with_min_len(256).for_each(|(a, ea)| {
        let (cols, vals) = p.row(a);
        let mut acc = SVector::<f64, R>::zeros();
        for (&j, b) in cols.iter().zip(vals) {
            acc += b.cast::<f64>() * x[j as usize];
        }
        *ea = acc;
    });
}

/// `here[1] = A⁻¹ here[0]` on the coarsest level.
fn solve_coarsest(numbers: &Levels, here: &mut [Vec<V6>; 5], c: &mut [f64], mem: &mut MemBuffer) {
    let [b, x, ..] = here;
    for (i, v) in b.iter().enumerate() {
        c[6 * i..6 * i + 6].copy_from_slice(v.as_slice());
    }
    let llt = LltRef::new(&numbers.symbolic, &numbers.factor);
    let nc = c.len();
    let need = numbers.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq);
    if mem.len() < need.unaligned_bytes_required() {
        *mem = MemBuffer::new(need);
    }
    llt.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(c, nc, 1),
        Par::Seq,
        MemStack::new(mem),
    );
    for (i, v) in x.iter_mut().enumerate() {
        *v = V6::from_column_slice(&c[6 * i..6 * i + 6]);
    }
}
