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
use super::levels::{Level, Levels};
use super::operator::OperatorScratch;
use super::projector::Projector;
use super::setup::Multilevel;

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

impl Multilevel {
    /// Scratch buffers for [`apply`](Self::apply).
    pub fn scratch(&self) -> MultilevelScratch {
        let st = &self.structure;
        let n = st.p32.rows();
        let mut sizes = vec![st.pt32.rows()];
        sizes.extend(st.coarse.links.iter().map(|l| l.pt.rows()));
        let levels = sizes.iter().map(|&m| std::array::from_fn(|_| vec![V6::zeros(); m])).collect();
        let coarsest = 6 * sizes.last().copied().unwrap_or(0);
        MultilevelScratch {
            r: vec![Vector3::zeros(); n],
            d: vec![Vector3::zeros(); n],
            t: vec![Vector3::zeros(); n],
            e: vec![Vector3::zeros(); n],
            k: self.op32.scratch(),
            levels,
            coarsest: vec![0.0; coarsest],
            mem: MemBuffer::new(
                self.levels.levels.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
            ),
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
        let inv = &con.inv_diag;
        let pi = &con.projector;
        d.par_iter_mut()
            .zip(r.par_iter())
            .zip(x.par_iter_mut())
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(a, ((da, ra), xa))| {
                *da = inv[a] * ra / c.theta;
                *xa += *da;
            });
        let mut rho = 1.0 / c.sigma;
        for _ in 1..self.params.degree {
            self.op_with(pi, d, s, t, |_, ta, y| *ta = y);
            let (c1, c2, next) = c.step(rho);
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
    d.par_iter_mut()
        .zip(r.par_iter())
        .zip(x.par_iter_mut())
        .enumerate()
        .with_min_len(COARSE_ROWS)
        .for_each(|(i, ((di, ri), xi))| {
            *di = inv[i].cast::<f64>() * ri / c.theta;
            *xi += *di;
        });
    let mut rho = 1.0 / c.sigma;
    for _ in 1..degree {
        multiply6(&level.a32, d, t);
        let (c1, c2, next) = c.step(rho);
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
        rho = next;
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
