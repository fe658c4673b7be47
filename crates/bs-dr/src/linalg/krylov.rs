//! Restarted GMRES with right preconditioning on nodal vectors (Saad & Schultz 1986; Saad,
//! *Iterative methods for sparse linear systems*, §9.3.2): the linear solver inside each
//! Newton iteration. Right preconditioning makes the residual it minimises the true residual
//! `b − A x`, the quantity the inexact Newton method controls. Deterministic for any thread
//! count (see [`super::sparse::dot`]); all buffers are caller-owned.

use bs_mesh::Vector3;
use rayon::prelude::*;

use super::sparse::norm;

/// A linear map on nodal vectors (`out = A v`), as the solvers pass operators around.
pub type NodalMap<'a> = dyn FnMut(&[Vector3<f64>], &mut [Vector3<f64>]) + 'a;

/// A linear map applied to `K` nodal vectors at once, `outs[j] = M ins[j]`
/// ([`Gmres::solve_batch`]'s preconditioner).
pub type BatchMap<'a, const K: usize> =
    dyn FnMut([&[Vector3<f64>]; K], [&mut [Vector3<f64>]; K]) + 'a;

/// Result of one [`Gmres::solve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GmresInfo {
    /// Operator (and preconditioner) applications.
    pub iterations: usize,
    /// `‖b − A x‖ / ‖b‖` at exit (the recurrence's value; exact at restarts).
    pub relative_residual: f64,
    /// Whether the relative residual reached the requested tolerance.
    pub converged: bool,
}

/// Workspace of restarted GMRES for vectors of one length.
#[derive(Debug)]
pub struct Gmres {
    restart: usize,
    v: Vec<Vec<Vector3<f64>>>,
    z: Vec<Vec<Vector3<f64>>>,
    w: Vec<Vector3<f64>>,
    h: Vec<Vec<f64>>,
    cs: Vec<f64>,
    sn: Vec<f64>,
    g: Vec<f64>,
    /// Whether a restart cycle that stalled ends the solve ([`stagnates`]).
    stall_exit: bool,
}

impl Gmres {
    /// Workspace for `n`-node vectors with `restart` iterations per cycle.
    pub fn new(n: usize, restart: usize) -> Self {
        let restart = restart.max(1);
        Gmres {
            restart,
            v: vec![vec![Vector3::zeros(); n]; restart + 1],
            z: vec![vec![Vector3::zeros(); n]; restart],
            w: vec![Vector3::zeros(); n],
            h: vec![vec![0.0; restart]; restart + 1],
            cs: vec![0.0; restart],
            sn: vec![0.0; restart],
            g: vec![0.0; restart + 1],
            stall_exit: false,
        }
    }

    /// Whether the next solves end after a restart cycle that stalled (default: no, they run
    /// to the tolerance or the iteration budget).
    pub fn set_stall_exit(&mut self, on: bool) {
        self.stall_exit = on;
    }

    /// Iterations per restart cycle.
    pub fn restart(&self) -> usize {
        self.restart
    }

    /// Length (nodal vectors) of the vectors it solves for.
    pub fn len(&self) -> usize {
        self.w.len()
    }

    /// Whether it solves for empty vectors.
    pub fn is_empty(&self) -> bool {
        self.w.is_empty()
    }

    /// Solves `A x = b` from `x = 0` to `‖b − A x‖ ≤ rtol ‖b‖` or `max_iterations`, with `op`
    /// computing `A v` and `prec` computing `M⁻¹ v` (right preconditioning: `A M⁻¹ y = b`,
    /// `x = M⁻¹ y`). With [`set_stall_exit`](Self::set_stall_exit), a restart cycle that
    /// stalled ends the solve early ([`stagnates`]).
    pub fn solve(
        &mut self,
        op: &mut NodalMap<'_>,
        prec: &mut NodalMap<'_>,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        rtol: f64,
        max_iterations: usize,
    ) -> GmresInfo {
        let mut lane = self.begin(op, b, x, (rtol, max_iterations));
        while self.needs_preconditioner(&lane) {
            let (v, z) = self.slots(lane.k);
            prec(v, z);
            self.advance(op, &mut lane, b, x);
        }
        lane.done.expect("a lane that needs nothing more has ended")
    }

    /// [`solve`](Self::solve) of `K` systems with one operator in lockstep, system `j` in
    /// workspace `gs[j]`: every iteration preconditions the `K` Krylov vectors together
    /// (`prec` gets them at once, so that a multilevel cycle reads its matrices once for
    /// all of them) and applies the operator to each. Each system stops at its own
    /// tolerance (`rtols[j]`) with the iterates [`solve`](Self::solve) gives it alone; one
    /// that has ended rides along in `prec` on its own stale vectors, the result thrown
    /// away.
    pub fn solve_batch<const K: usize>(
        gs: &mut [Gmres; K],
        op: &mut NodalMap<'_>,
        prec: &mut BatchMap<'_, K>,
        b: [&[Vector3<f64>]; K],
        mut x: [&mut [Vector3<f64>]; K],
        (rtols, max_iterations): ([f64; K], usize),
    ) -> [GmresInfo; K] {
        let mut lanes: Vec<Lane> = gs
            .iter_mut()
            .zip(b.iter().zip(x.iter_mut()))
            .zip(rtols)
            .map(|((g, (bj, xj)), rtol)| g.begin(op, bj, xj, (rtol, max_iterations)))
            .collect();
        loop {
            let active: Vec<bool> =
                gs.iter().zip(&lanes).map(|(g, l)| g.needs_preconditioner(l)).collect();
            if !active.contains(&true) {
                break;
            }
            let (ins, outs): (Vec<_>, Vec<_>) = gs
                .iter_mut()
                .zip(&lanes)
                .zip(&active)
                .map(|((g, lane), &on)| g.slots(if on { lane.k } else { 0 }))
                .unzip();
            let ins: [&[Vector3<f64>]; K] = ins.try_into().expect("K lanes");
            let outs: [&mut [Vector3<f64>]; K] = outs.try_into().expect("K lanes");
            prec(ins, outs);
            for (j, g) in gs.iter_mut().enumerate().filter(|&(j, _)| active[j]) {
                g.advance(op, &mut lanes[j], b[j], x[j]);
            }
        }
        std::array::from_fn(|j| lanes[j].done.expect("every lane has ended"))
    }

    /// The Krylov vector `k` and the slot of its preconditioned image.
    fn slots(&mut self, k: usize) -> (&[Vector3<f64>], &mut [Vector3<f64>]) {
        (&self.v[k], &mut self.z[k])
    }

    /// Starts a solve of `A x = b` (`x = 0`); ended at once when `b` is zero or not finite
    /// (or the budget is zero).
    fn begin(
        &mut self,
        op: &mut NodalMap<'_>,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        (rtol, max_iterations): (f64, usize),
    ) -> Lane {
        x.iter_mut().for_each(|v| *v = Vector3::zeros());
        let bn = norm(b);
        let mut lane = Lane {
            bn,
            beta: bn,
            cycle_start: bn,
            k: 0,
            total: 0,
            breakdown: false,
            rtol,
            max_iterations,
            done: None,
        };
        if bn == 0.0 || !bn.is_finite() {
            let info = GmresInfo { iterations: 0, relative_residual: 0.0, converged: bn == 0.0 };
            lane.done = Some(info);
            return lane;
        }
        // r0 = b (x = 0).
        self.v[0].copy_from_slice(b);
        self.open_cycle(&mut lane);
        if !self.inside_cycle(&lane) {
            self.close_cycle(op, &mut lane, b, x);
        }
        lane
    }

    /// Whether `lane` waits for `M⁻¹ v_k` in `z_k`.
    fn needs_preconditioner(&self, lane: &Lane) -> bool {
        lane.done.is_none() && self.inside_cycle(lane)
    }

    fn inside_cycle(&self, lane: &Lane) -> bool {
        lane.k < self.restart && lane.total < lane.max_iterations
    }

    /// A restart cycle from `v_0 = r / β`.
    fn open_cycle(&mut self, lane: &mut Lane) {
        lane.cycle_start = lane.beta;
        let inv = 1.0 / lane.beta;
        self.v[0].par_iter_mut().with_min_len(2048).for_each(|a| *a *= inv);
        self.g.iter_mut().for_each(|v| *v = 0.0);
        self.g[0] = lane.beta;
        lane.k = 0;
        lane.breakdown = false;
    }

    /// One iteration of `lane` with `z_k = M⁻¹ v_k` in place: `w = A z_k` orthogonalised
    /// against the basis, the Hessenberg column rotated; the cycle closed when it ends.
    fn advance(
        &mut self,
        op: &mut NodalMap<'_>,
        lane: &mut Lane,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
    ) {
        let k = lane.k;
        op(&self.z[k], &mut self.w);
        lane.total += 1;
        // Classical Gram–Schmidt twice (CGS2): as stable as modified Gram–Schmidt, with all
        // inner products of a sweep in one pass over the vectors.
        let basis = &self.v[..=k];
        let h1 = multi_dot(basis, &self.w);
        subtract(basis, &h1, &mut self.w);
        let h2 = multi_dot(basis, &self.w);
        let hn = subtract(basis, &h2, &mut self.w).sqrt();
        for j in 0..=k {
            self.h[j][k] = h1[j] + h2[j];
        }
        self.h[k + 1][k] = hn;
        for j in 0..k {
            let t = self.cs[j] * self.h[j][k] + self.sn[j] * self.h[j + 1][k];
            self.h[j + 1][k] = -self.sn[j] * self.h[j][k] + self.cs[j] * self.h[j + 1][k];
            self.h[j][k] = t;
        }
        let d = self.h[k][k].hypot(self.h[k + 1][k]);
        if d == 0.0 || !d.is_finite() {
            lane.breakdown = true;
            return self.close_cycle(op, lane, b, x);
        }
        self.cs[k] = self.h[k][k] / d;
        self.sn[k] = self.h[k + 1][k] / d;
        self.h[k][k] = d;
        self.h[k + 1][k] = 0.0;
        self.g[k + 1] = -self.sn[k] * self.g[k];
        self.g[k] *= self.cs[k];
        lane.k = k + 1;
        if self.g[k + 1].abs() <= lane.rtol * lane.bn || hn == 0.0 {
            return self.close_cycle(op, lane, b, x);
        }
        let inv = 1.0 / hn;
        let (w, next) = (&self.w, &mut self.v[k + 1]);
        next.par_iter_mut().zip(w.par_iter()).with_min_len(2048).for_each(|(a, b)| *a = b * inv);
        if !self.inside_cycle(lane) {
            self.close_cycle(op, lane, b, x);
        }
    }

    /// The end of a restart cycle: `x += Z y` with `H y = g`, then the end of the solve or
    /// a restart from the true residual (and, should the new cycle have no room, its end).
    fn close_cycle(
        &mut self,
        op: &mut NodalMap<'_>,
        lane: &mut Lane,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
    ) {
        loop {
            let k = lane.k;
            let mut y = vec![0.0; k];
            for i in (0..k).rev() {
                let mut s = self.g[i];
                for j in i + 1..k {
                    s -= self.h[i][j] * y[j];
                }
                y[i] = s / self.h[i][i];
            }
            let z = &self.z[..k];
            x.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(i, a)| {
                for (zj, &yj) in z.iter().zip(&y) {
                    *a += zj[i] * yj;
                }
            });
            let (bn, rtol) = (lane.bn, lane.rtol);
            let estimate = self.g[k].abs() / bn;
            if estimate <= rtol || lane.total >= lane.max_iterations || lane.breakdown {
                let converged = estimate <= rtol;
                let info =
                    GmresInfo { iterations: lane.total, relative_residual: estimate, converged };
                lane.done = Some(info);
                return;
            }
            // Restart from the true residual.
            op(x, &mut self.w);
            let (v0, w) = (&mut self.v[0], &self.w);
            v0.par_iter_mut().zip(b.par_iter()).zip(w.par_iter()).with_min_len(2048).for_each(
                |((r, bi), wi)| {
                    *r = bi - wi;
                },
            );
            lane.beta = norm(&self.v[0]);
            let ratio = lane.beta / bn;
            if lane.beta <= rtol * bn
                || (self.stall_exit && stagnates(lane.beta / lane.cycle_start))
            {
                let converged = lane.beta <= rtol * bn;
                let info =
                    GmresInfo { iterations: lane.total, relative_residual: ratio, converged };
                lane.done = Some(info);
                return;
            }
            self.open_cycle(lane);
            if self.inside_cycle(lane) {
                return;
            }
        }
    }
}

/// Where one system of a solve stands (between iterations).
#[derive(Debug, Clone, Copy)]
struct Lane {
    /// `‖b‖`, the residual norm the cycle started from, and the cycle's position.
    bn: f64,
    beta: f64,
    cycle_start: f64,
    k: usize,
    total: usize,
    breakdown: bool,
    rtol: f64,
    max_iterations: usize,
    /// The outcome, once ended.
    done: Option<GmresInfo>,
}

/// Whether a restart cycle that reduced the residual by the factor `ratio` has stalled:
/// by less than [`STALLED`]. On the MNI152 brain falling onto its skull under gravity,
/// GMRES(40) reached 5.7e-2 in its first cycle and 4.2e-2 after 200 iterations (2.8 s of a
/// 9.2 s solve) where 1e-2 was asked.
fn stagnates(ratio: f64) -> bool {
    ratio >= STALLED
}

/// A restart cycle that leaves more than this fraction of the residual it started from has
/// stalled. Measured (`brainshift run`): the MNI152 brain under gravity takes 302 GMRES
/// iterations at 0.8 against 517 without the exit, the same brain hanging from its stem 28
/// Newton iterations against 65 (at 0.9: 65). Used only under a body force alone
/// (`nk::linear`); docs/decisions.md has what it did to the prescribed-displacement cases.
const STALLED: f64 = 0.8;

/// Nodes per chunk of the fused passes (fixed: the sums do not depend on the thread count).
const CHUNK: usize = 2048;

/// `Vᵀ w` for the vectors `v`, in one pass: per chunk the partial products of every vector,
/// then the chunks summed in order.
fn multi_dot(v: &[Vec<Vector3<f64>>], w: &[Vector3<f64>]) -> Vec<f64> {
    let m = v.len();
    let partial: Vec<Vec<f64>> = w
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, wc)| {
            let start = c * CHUNK;
            let mut acc = vec![0.0; m];
            for (i, wi) in wc.iter().enumerate() {
                for (a, vj) in acc.iter_mut().zip(v) {
                    *a += vj[start + i].dot(wi);
                }
            }
            acc
        })
        .collect();
    let mut out = vec![0.0; m];
    for p in &partial {
        for (o, x) in out.iter_mut().zip(p) {
            *o += x;
        }
    }
    out
}

/// `w −= V h` in one pass; returns `‖w‖²` after the update (chunks summed in order).
fn subtract(v: &[Vec<Vector3<f64>>], h: &[f64], w: &mut [Vector3<f64>]) -> f64 {
    let partial: Vec<f64> = w
        .par_chunks_mut(CHUNK)
        .enumerate()
        .map(|(c, wc)| {
            let start = c * CHUNK;
            let mut n2 = 0.0;
            for (i, wi) in wc.iter_mut().enumerate() {
                for (vj, &hj) in v.iter().zip(h) {
                    *wi -= vj[start + i] * hj;
                }
                n2 += wi.norm_squared();
            }
            n2
        })
        .collect();
    partial.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagonally dominant nonsymmetric nodal operator and its exact solve.
    #[test]
    fn gmres_solves_a_nonsymmetric_system_across_restarts() {
        let n = 200;
        let op = |x: &[Vector3<f64>], y: &mut [Vector3<f64>]| {
            for i in 0..x.len() {
                let left = if i > 0 { x[i - 1] } else { Vector3::zeros() };
                let right = if i + 1 < x.len() { x[i + 1] } else { Vector3::zeros() };
                y[i] = x[i] * (4.0 + (i % 7) as f64) - left * 1.5 - right * 0.5
                    + Vector3::new(x[i].y, -x[i].x, 0.3 * x[i].z);
            }
        };
        let x_true: Vec<Vector3<f64>> =
            (0..n).map(|i| Vector3::new((i as f64).sin(), 1.0, (i % 5) as f64)).collect();
        let mut b = vec![Vector3::zeros(); n];
        op(&x_true, &mut b);
        let mut x = vec![Vector3::zeros(); n];
        let mut g = Gmres::new(n, 8);
        let mut op_mut = op;
        let mut id = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| z.copy_from_slice(r);
        let info = g.solve(&mut op_mut, &mut id, &b, &mut x, 1e-10, 500);
        assert!(info.converged, "{info:?}");
        assert!(info.iterations > 8, "the test must cross a restart");
        let err = x.iter().zip(&x_true).map(|(a, b)| (a - b).amax()).fold(0.0, f64::max);
        assert!(err < 1e-8, "error {err}");
        // The reported residual is the true one within round-off.
        let mut r = vec![Vector3::zeros(); n];
        op_mut(&x, &mut r);
        let true_res = norm(&r.iter().zip(&b).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(&b);
        assert!(true_res <= 1e-9, "true residual {true_res}");
    }

    /// GMRES(m) on the cyclic shift makes no progress until its Krylov space spans the whole
    /// space (m < n): the first cycle leaves the residual where it was, and with the stall
    /// exit the solve stops there instead of spending its budget.
    #[test]
    fn a_stalled_restart_cycle_ends_the_solve() {
        let n = 50;
        let mut op = |x: &[Vector3<f64>], y: &mut [Vector3<f64>]| {
            for i in 0..x.len() {
                y[i] = x[(i + 1) % x.len()];
            }
        };
        let mut b = vec![Vector3::zeros(); n];
        b[0] = Vector3::new(1.0, 2.0, 3.0);
        let mut x = vec![Vector3::zeros(); n];
        let mut g = Gmres::new(n, 10);
        let mut id = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| z.copy_from_slice(r);
        let info = g.solve(&mut op, &mut id, &b, &mut x, 1e-6, 200);
        // Without the exit it spends its budget (the 50-dimensional space is spanned only
        // by one cycle of 50).
        assert!(!info.converged && info.iterations == 200, "{info:?}");
        g.set_stall_exit(true);
        let info = g.solve(&mut op, &mut id, &b, &mut x, 1e-6, 200);
        assert!(!info.converged && info.iterations == 10, "{info:?}");
        assert!((info.relative_residual - 1.0).abs() < 1e-12, "{info:?}");
    }

    /// A batch in lockstep gives each system what its own solve gives, bit for bit: the
    /// iterates, the iteration count and the residual, for systems that end at different
    /// iterations (one of them zero, ended before the first) and across restarts.
    #[test]
    fn a_batch_gives_each_system_its_own_solve() {
        let n = 120;
        let mut op = |x: &[Vector3<f64>], y: &mut [Vector3<f64>]| {
            for i in 0..x.len() {
                let left = if i > 0 { x[i - 1] } else { Vector3::zeros() };
                y[i] = x[i] * (3.0 + (i % 5) as f64) - left * 1.2 + Vector3::new(x[i].y, 0.0, 0.0);
            }
        };
        let diag = |i: usize| 1.0 / (3.0 + (i % 5) as f64);
        let jacobi = |r: &[Vector3<f64>], z: &mut [Vector3<f64>]| {
            z.iter_mut().zip(r).enumerate().for_each(|(i, (z, r))| *z = r * diag(i));
        };
        let bs: [Vec<Vector3<f64>>; 3] = [
            (0..n).map(|i| Vector3::new(1.0, (i as f64).cos(), 0.0)).collect(),
            vec![Vector3::zeros(); n],
            (0..n).map(|i| Vector3::new(0.0, 0.0, if i % 9 == 0 { 5.0 } else { 0.1 })).collect(),
        ];
        let tol = ([1e-9, 1e-9, 1e-7], 400);
        let mut single = Vec::new();
        for (b, rtol) in bs.iter().zip(tol.0) {
            let mut x = vec![Vector3::zeros(); n];
            let mut prec = jacobi;
            let info = Gmres::new(n, 6).solve(&mut op, &mut prec, b, &mut x, rtol, tol.1);
            single.push((x, info));
        }
        let mut gs = std::array::from_fn(|_| Gmres::new(n, 6));
        let mut xs: [Vec<Vector3<f64>>; 3] = std::array::from_fn(|_| vec![Vector3::zeros(); n]);
        let mut calls = 0;
        let mut prec = |r: [&[Vector3<f64>]; 3], z: [&mut [Vector3<f64>]; 3]| {
            calls += 1;
            r.into_iter().zip(z).for_each(|(r, z)| jacobi(r, z));
        };
        let b = bs.each_ref().map(|v| &v[..]);
        let x = xs.each_mut().map(|v| &mut v[..]);
        let infos = Gmres::solve_batch(&mut gs, &mut op, &mut prec, b, x, tol);
        let most = single.iter().map(|s| s.1.iterations).max().unwrap();
        assert_eq!(calls, most, "one batched preconditioning per lockstep iteration");
        for (j, (x, info)) in single.iter().enumerate() {
            assert_eq!(xs[j], *x, "system {j}");
            assert_eq!(infos[j].iterations, info.iterations, "system {j}");
            assert_eq!(infos[j].relative_residual, info.relative_residual, "system {j}");
            assert!(info.converged, "system {j}: {info:?}");
        }
        assert_eq!(infos[1].iterations, 0, "a zero right-hand side needs no iteration");
        assert!(infos[0].iterations > 6 && infos[0].iterations != infos[2].iterations);
    }

    #[test]
    fn a_cycle_stalls_when_it_keeps_a_fifth_of_its_residual() {
        // The MNI152 gravity solve's later cycles: 0.93 per cycle.
        assert!(stagnates(0.93) && stagnates(1.0) && stagnates(0.8));
        // A first cycle from 1 to 5.7e-2, and a slow but working one.
        assert!(!stagnates(5.7e-2) && !stagnates(0.7));
    }
}
