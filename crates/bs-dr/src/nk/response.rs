//! The linear response at a converged state: how the answer moves when the equations it
//! solves change a little (a measured point's noise, a load parameter), without another
//! nonlinear solve. At an equilibrium `r(u) = 0` a change `δr` of the residual moves the
//! answer by `δu = −J⁻¹ δr`, with `J` the tangent there: the elements' (forward
//! differences of their forces, as the Newton steps), the data springs' linearised at the
//! state, and the contact nodes held on their features as the state holds them (their
//! normal direction removed, as the fixed components are). Each response is one GMRES
//! solve with the state's preconditioner: the preconditioner and the active set are made
//! once, for any number of responses (an uncertainty's samples). Many responses at once
//! ([`Response::solve_all`]) go through GMRES in batches of [`BATCH`] in lockstep: the
//! multilevel cycle then reads its matrices once for the batch, which is most of a cycle's
//! cost. [`Response::refine_all`] carries responses solved loosely on to a tighter
//! tolerance from where they stopped.

use std::time::{Duration, Instant};

use bs_mesh::Vector3;

use super::Work;
use super::iterate::Iterate;
use super::linear::{self, Linearisation, tangent_product};
use super::outcome::NewtonKrylovError;
use super::problem::Context;
use super::{NewtonKrylov, Preparation};
use crate::contact::Contact;
use crate::data::DataTerm;
use crate::linalg::krylov::{Gmres, GmresInfo, NodalMap};
use crate::linalg::multilevel::MultilevelBatchScratch;
use crate::linalg::sparse::{max_abs, norm};
use crate::loads::Loads;
use crate::model::Model;

/// What one response solve did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResponseInfo {
    /// GMRES iterations.
    pub iterations: usize,
    /// The relative residual reached, and whether it reached the tolerance asked for.
    pub relative_residual: f64,
    pub converged: bool,
}

/// Right-hand sides that [`Response::solve_all`] solves together: four, as beyond four the
/// twelve accumulators of a row of the batched mesh product no longer fit the sixteen AVX2
/// registers (on a 15,625-node block the product costs 0.125 ms per vector in a batch of
/// four against 0.324 ms alone).
pub const BATCH: usize = 4;

/// The tangent at a converged state, ready to give responses
/// ([`NewtonKrylov::with_response`]).
pub struct Response<'p, 'a> {
    pb: &'p Context<'a>,
    it: Iterate<'a>,
    work: Work,
    /// The buffers of [`solve_all`](Self::solve_all), made at its first call.
    batch: Option<Box<Batch>>,
}

/// Buffers of one batch of [`Response::solve_all`].
struct Batch {
    rhs: [Vec<Vector3<f64>>; BATCH],
    x: [Vec<Vector3<f64>>; BATCH],
    gmres: [Gmres; BATCH],
    cycle: MultilevelBatchScratch<BATCH>,
}

impl std::fmt::Debug for Response<'_, '_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Response").field("iterations", &self.work.linear).finish_non_exhaustive()
    }
}

impl Response<'_, '_> {
    /// The response `out = δu` to the residual change `residual_change = δr` (nodal
    /// forces: the change of internal minus external forces at the state), to GMRES's
    /// relative residual `rtol`. Fixed components and held contact normals of `δr` are
    /// ignored and stay zero in `δu`.
    pub fn solve(
        &mut self,
        residual_change: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
        rtol: f64,
    ) -> Result<ResponseInfo, NewtonKrylovError> {
        let n = self.it.u.len();
        if residual_change.len() != n || out.len() != n {
            return Err(NewtonKrylovError::Unsupported {
                what: "a residual change or response of another length than the model's nodes",
                fix: "give one vector per node",
            });
        }
        let it = &mut self.it;
        it.delta.iter_mut().zip(residual_change).for_each(|(l, r)| *l = -r);
        let lin = Linearisation {
            model: self.pb.model,
            data: &it.data,
            dead: self.pb.loads.forces(),
            u: &it.u,
            f: &it.f,
            particular: &it.particular,
            springs: &it.springs,
            cons: &it.cons,
            tl: it.pre.get(),
            load: Some(&it.delta),
            stall_exit: false,
        };
        let max = self.pb.params.max_linear_iterations;
        let info = linear::solve(&lin, &mut it.linear, &mut it.ws, out, rtol, max, &mut self.work)
            .map_err(NewtonKrylovError::inverted)?;
        let (iterations, relative_residual) = (info.iterations, info.relative_residual);
        Ok(ResponseInfo { iterations, relative_residual, converged: info.converged })
    }

    /// The responses `outs[i] = δu_i` to `changes[i]` as [`solve`](Self::solve) gives
    /// them, in batches of [`BATCH`] solved in lockstep (each to the relative residual
    /// `rtol`, with the iterates it has alone). A nearly incompressible model solved in the
    /// mixed form solves them one by one.
    pub fn solve_all(
        &mut self,
        changes: &[Vec<Vector3<f64>>],
        outs: &mut [Vec<Vector3<f64>>],
        rtol: f64,
    ) -> Result<Vec<ResponseInfo>, NewtonKrylovError> {
        matching(self.it.u.len(), changes, outs)?;
        if self.it.pre.get().split().is_some() {
            let pairs = changes.iter().zip(outs.iter_mut());
            return pairs.map(|(c, o)| self.solve(c, o, rtol)).collect();
        }
        self.batches(changes, outs, rtol, false)
    }

    /// The responses `outs` of [`solve_all`](Self::solve_all) at a looser tolerance carried
    /// on to `rtol`, each from where it is: the correction solves the residual left, to the
    /// relative residual that makes the whole `rtol` of its change's. A response already
    /// there is left as it is (no iterations).
    pub fn refine_all(
        &mut self,
        changes: &[Vec<Vector3<f64>>],
        outs: &mut [Vec<Vector3<f64>>],
        rtol: f64,
    ) -> Result<Vec<ResponseInfo>, NewtonKrylovError> {
        matching(self.it.u.len(), changes, outs)?;
        if self.it.pre.get().split().is_some() {
            return Err(NewtonKrylovError::Unsupported {
                what: "refining responses of a model solved in the mixed form",
                fix: "solve the responses at the tolerance wanted with `solve_all`",
            });
        }
        self.batches(changes, outs, rtol, true)
    }

    /// [`solve_all`](Self::solve_all) (`warm`: [`refine_all`](Self::refine_all)) batch by
    /// batch.
    fn batches(
        &mut self,
        changes: &[Vec<Vector3<f64>>],
        outs: &mut [Vec<Vector3<f64>>],
        rtol: f64,
        warm: bool,
    ) -> Result<Vec<ResponseInfo>, NewtonKrylovError> {
        let mut infos = Vec::with_capacity(changes.len());
        for (cs, os) in changes.chunks(BATCH).zip(outs.chunks_mut(BATCH)) {
            let info = self.batch(cs, warm.then_some(&*os), rtol);
            let x = &self.batch.as_ref().expect("made by the batch").x;
            for (j, o) in os.iter_mut().enumerate() {
                let i = info[j];
                o.copy_from_slice(&x[j]);
                let (iterations, relative_residual) = (i.iterations, i.relative_residual);
                infos.push(ResponseInfo { iterations, relative_residual, converged: i.converged });
            }
        }
        Ok(infos)
    }

    /// GMRES in lockstep on at most [`BATCH`] changes `cs` (the rest of the batch zero), the
    /// responses left in the batch's `x`; from the responses `warm` when given (each to the
    /// relative residual `rtol` of its change's, the lane's reported residual relative to
    /// the residual it started from).
    fn batch(
        &mut self,
        cs: &[Vec<Vector3<f64>>],
        warm: Option<&[Vec<Vector3<f64>>]>,
        rtol: f64,
    ) -> [GmresInfo; BATCH] {
        let Response { pb, it, work, batch } = self;
        let n = it.u.len();
        let b = batch.get_or_insert_with(|| {
            let v = || std::array::from_fn(|_| vec![Vector3::zeros(); n]);
            let restart = it.linear.gmres.restart();
            let gmres = std::array::from_fn(|_| Gmres::new(n, restart));
            let cycle = it.pre.get().batch_scratch();
            Box::new(Batch { rhs: v(), x: v(), gmres, cycle })
        });
        let lin = Linearisation {
            model: pb.model,
            data: &it.data,
            dead: pb.loads.forces(),
            u: &it.u,
            f: &it.f,
            particular: &it.particular,
            springs: &it.springs,
            cons: &it.cons,
            tl: it.pre.get(),
            load: None,
            stall_exit: false,
        };
        let umax = max_abs(lin.u);
        let (up, ws) = (&mut it.linear.up, &mut it.ws);
        let mut products = Work::default();
        let mut op = |v: &[Vector3<f64>], out: &mut [Vector3<f64>]| {
            tangent_product(&lin, umax, (up, &mut *ws), &mut products, v, out);
        };
        let mut rtols = [rtol; BATCH];
        for (j, rhs) in b.rhs.iter_mut().enumerate() {
            match cs.get(j) {
                Some(c) => rhs.iter_mut().zip(c).for_each(|(r, d)| *r = -d),
                None => rhs.iter_mut().for_each(|r| *r = Vector3::zeros()),
            }
            lin.cons.projector.apply(rhs);
            if let Some(x0) = warm.and_then(|w| w.get(j)) {
                rtols[j] = left_to_solve(rhs, x0, &mut b.x[j], &mut op, rtol);
            }
        }
        let mut prec_time = Duration::ZERO;
        let (tl, cons, cycle) = (lin.tl, lin.cons, &mut b.cycle);
        let mut prec = |r: [&[Vector3<f64>]; BATCH], z: [&mut [Vector3<f64>]; BATCH]| {
            let t = Instant::now();
            tl.apply_batch(cons, r, z, cycle);
            prec_time += t.elapsed();
        };
        let rhs = b.rhs.each_ref().map(|v| &v[..]);
        let x = b.x.each_mut().map(|v| &mut v[..]);
        let max = pb.params.max_linear_iterations;
        let info = Gmres::solve_batch(&mut b.gmres, &mut op, &mut prec, rhs, x, (rtols, max));
        work.forces += products.forces;
        work.time.forces += products.time.forces;
        work.time.preconditioner += prec_time;
        work.linear += info.iter().map(|i| i.iterations).sum::<usize>();
        for (j, x) in b.x.iter_mut().enumerate() {
            it.cons.projector.apply(x);
            if let Some(x0) = warm.and_then(|w| w.get(j)) {
                x.iter_mut().zip(x0).for_each(|(x, a)| *x += a);
            }
        }
        info
    }

    /// GMRES iterations of every response so far.
    pub fn gmres_iterations(&self) -> usize {
        self.work.linear
    }
}

/// `Err` unless there is one response buffer per change, each of `n` nodes.
fn matching(
    n: usize,
    changes: &[Vec<Vector3<f64>>],
    outs: &[Vec<Vector3<f64>>],
) -> Result<(), NewtonKrylovError> {
    if changes.len() != outs.len() || changes.iter().chain(outs).any(|v| v.len() != n) {
        return Err(NewtonKrylovError::Unsupported {
            what: "residual changes and responses of other counts or lengths",
            fix: "give one response buffer per change, each one vector per node",
        });
    }
    Ok(())
}

/// The residual `b − A x0` into `b` (`t` a buffer), and the relative residual its
/// correction must reach for `x0` plus it to have `rtol` of `b`'s; the residual zeroed (no
/// correction) where `x0` already has it.
fn left_to_solve(
    b: &mut [Vector3<f64>],
    x0: &[Vector3<f64>],
    t: &mut [Vector3<f64>],
    op: &mut NodalMap<'_>,
    rtol: f64,
) -> f64 {
    let target = rtol * norm(b);
    op(x0, t);
    b.iter_mut().zip(t.iter()).for_each(|(b, t)| *b -= t);
    let left = norm(b);
    if left <= target {
        b.iter_mut().for_each(|b| *b = Vector3::zeros());
        return rtol;
    }
    target / left
}

impl NewtonKrylov {
    /// Calls `f` with the tangent at the converged displacements `state` of `loads`
    /// (`data` linearised there, the contact's active set chosen there): see [`Response`].
    /// `prep` is the preparation the state was solved with.
    #[allow(clippy::too_many_arguments)]
    pub fn with_response<R>(
        &self,
        model: &Model,
        loads: &Loads,
        prep: &Preparation,
        state: &[Vector3<f64>],
        contact: &mut dyn Contact,
        data: &mut dyn DataTerm,
        f: impl FnOnce(&mut Response<'_, '_>) -> R,
    ) -> Result<R, NewtonKrylovError> {
        let pb = Context::new(&self.params, model, loads, prep, &*contact, Some(state))?;
        let mut work = Work::default();
        let mut it = Iterate::new(&pb, &mut work, data)?;
        it.active.choose(contact, &pb.nodes, &pb.node_state(&it.u, &it.f))?;
        it.active.constrain(
            it.pre.get(),
            &mut it.cons,
            &pb.nodes,
            &pb.node_state(&it.u, &it.f),
            &mut it.particular,
            &mut it.springs,
        );
        // The response moves from the state as it is: no particular displacement.
        it.particular.iter_mut().for_each(|p| *p = Vector3::zeros());
        if it.pre.stale(pb.model, &it.u, pb.params.rebuild_strain)
            && it.pre.rebuild(pb.model, &it.u, &pb.fixed, &it.cons.projector, &mut work)
        {
            it.cons = it.pre.get().constraints_like(&it.cons);
            it.linear.tl = it.pre.get().scratch();
        }
        it.pre.get().constrain_coarse(&mut it.cons);
        let mut response = Response { pb: &pb, it, work, batch: None };
        Ok(f(&mut response))
    }
}
