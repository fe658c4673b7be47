//! Applying the preconditioner: one symmetric cycle `x = B b` for `Π K₀ Π` (Chebyshev
//! pre-smoothing, coarse correction, Chebyshev post-smoothing), on caller-owned scratch.

use bs_mesh::Vector3;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::LltRef;
use faer::{Conj, MatMut, Par};
use rayon::prelude::*;

use super::constraints::Constraints;
use super::operator::OperatorScratch;
use super::projector::Projector;
use super::setup::TwoLevel;

/// Nodes per rayon task in the cycle's passes: few enough tasks that the fork-join overhead
/// stays small next to the work of a pass.
const ROWS: usize = 2048;

/// Caller-owned buffers of [`TwoLevel::apply`].
pub struct TwoLevelScratch {
    r: Vec<Vector3<f64>>,
    d: Vec<Vector3<f64>>,
    t: Vec<Vector3<f64>>,
    e: Vec<Vector3<f64>>,
    k: OperatorScratch,
    coarse: Vec<f64>,
    mem: MemBuffer,
}

impl std::fmt::Debug for TwoLevelScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TwoLevelScratch")
            .field("nodes", &self.r.len())
            .field("coarse", &self.coarse.len())
            .finish()
    }
}

impl TwoLevel {
    /// Scratch buffers for [`apply`](Self::apply).
    pub fn scratch(&self) -> TwoLevelScratch {
        let n = self.p.rows();
        let nc = self.pt.rows();
        TwoLevelScratch {
            r: vec![Vector3::zeros(); n],
            d: vec![Vector3::zeros(); n],
            t: vec![Vector3::zeros(); n],
            e: vec![Vector3::zeros(); n],
            k: self.op32.scratch(),
            coarse: vec![0.0; nc],
            mem: MemBuffer::new(self.coarse.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)),
        }
    }

    /// `f(a, (Π K₀ x)_a)` for every node `a` (single-precision operator; `x` in the range
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

    /// Chebyshev smoothing from zero: `x += p(D⁻¹A) D⁻¹ r`; `r` is overwritten.
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
        let hi = self.lambda_max;
        let lo = hi * self.params.lower;
        let theta = 0.5 * (hi + lo);
        let delta = 0.5 * (hi - lo);
        let sigma = theta / delta;
        let mut rho = 1.0 / sigma;
        let inv = &con.inv_diag;
        let pi = &con.projector;
        d.par_iter_mut()
            .zip(r.par_iter())
            .zip(x.par_iter_mut())
            .enumerate()
            .with_min_len(ROWS)
            .for_each(|(a, ((da, ra), xa))| {
                *da = inv[a] * ra / theta;
                *xa += *da;
            });
        for _ in 1..self.params.degree {
            self.op_with(pi, d, s, t, |_, ta, y| *ta = y);
            let rho_new = 1.0 / (2.0 * sigma - rho);
            let (c1, c2) = (rho_new * rho, 2.0 * rho_new / delta);
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
            rho = rho_new;
        }
    }

    /// `x = B b`: one symmetric two-level cycle for `Π K₀ Π`, `b` in the range of `Π`.
    pub fn apply(
        &self,
        con: &Constraints,
        b: &[Vector3<f64>],
        x: &mut [Vector3<f64>],
        s: &mut TwoLevelScratch,
    ) {
        let TwoLevelScratch { r, d, t, e, k, coarse, mem } = s;
        let pi = &con.projector;
        x.par_iter_mut().with_min_len(ROWS).for_each(|v| *v = Vector3::zeros());
        r.copy_from_slice(b);
        self.chebyshev(con, r, x, d, t, k);
        // Residual after pre-smoothing, coarse correction, and the residual after it.
        self.op_with(pi, x, k, r, |a, ra, y| *ra = b[a] - y);
        self.coarse_correct(con, r, e, coarse, mem);
        x.par_iter_mut().zip(e.par_iter()).with_min_len(ROWS).for_each(|(xa, ea)| *xa += ea);
        self.op_with(pi, e, k, r, |_, ra, y| *ra -= y);
        // Post-smoothing accumulates into x directly.
        self.chebyshev(con, r, x, d, t, k);
    }

    /// `e = Π P A_c⁻¹ Pᵀ Π r`, `A_c` the constraints' coarse matrix if they have one.
    fn coarse_correct(
        &self,
        con: &Constraints,
        r: &[Vector3<f64>],
        e: &mut [Vector3<f64>],
        c: &mut [f64],
        mem: &mut MemBuffer,
    ) {
        c.par_iter_mut().enumerate().with_min_len(64).for_each(|(i, ci)| {
            let (nodes, vals) = self.pt.row(i);
            let mut acc = 0.0;
            for (&a, v) in nodes.iter().zip(vals) {
                let ra = &r[a as usize];
                acc += f64::from(v[0]) * ra.x + f64::from(v[1]) * ra.y + f64::from(v[2]) * ra.z;
            }
            *ci = acc;
        });
        let coarse = con.coarse.as_deref().unwrap_or(&self.coarse);
        let llt = LltRef::new(&coarse.symbolic, &coarse.values);
        let nc = c.len();
        let need = coarse.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq);
        if mem.len() < need.unaligned_bytes_required() {
            *mem = MemBuffer::new(need);
        }
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(c, nc, 1),
            Par::Seq,
            MemStack::new(mem),
        );
        let c: &[f64] = c;
        let pi = &con.projector;
        e.par_iter_mut().enumerate().with_min_len(256).for_each(|(a, ea)| {
            let (cols, vals) = self.p.row(a);
            let mut acc = Vector3::zeros();
            for (&j, v) in cols.iter().zip(vals) {
                let cj = c[j as usize];
                acc += Vector3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])) * cj;
            }
            *ea = acc;
        });
        pi.apply(e);
    }
}
